//! A bounding volume hierarchy built with the binned surface area heuristic (Wald 2007),
//! flattened depth-first so the left child follows its parent.
//!
//! Closest-hit queries break ties in favour of opaque primitives: where a null (index-matched)
//! medium boundary lies in the same plane as a wall, the wall is what the ray hits. Without that
//! rule a ray can cross the null face, be lifted off it and pass the wall: the light leak the
//! coplanar tests in `tests/spec/geometry.rs` guard against.
//! Book: "Scenes and geometry".

use std::mem::MaybeUninit;

use glam::Vec3;

use super::leaf::{self, Block, LaneRays, QuadLanes};
use super::pages::Pages;
use super::wide::{collapse, Binary, Child, Node4, Node8, RayLanes, RayLanes8, Slot, Wide};
use super::wide::{WIDTH, WIDTH8};
use super::{shape::Hit, Aabb, Primitive, Ray};

const BINS: usize = 12;
const MAX_LEAF: usize = 2;
/// Deepest level the build creates: below it everything left becomes one leaf. Traversal keeps
/// its to-do list in a fixed stack of this size, which therefore can never overflow (before
/// this limit, a push onto a full stack was silently dropped, losing a subtree).
pub const MAX_DEPTH: usize = 64;
/// A primitive's box is split while its surface area exceeds this multiple of the mean box's
/// ([`split_references`]).
const SPLIT_AREA: f32 = 8.0;
/// References the splitting may add, per primitive of the scene.
const SPLIT_BUDGET: usize = 1;
/// SAH cost of one traversal step relative to one test of a leaf ([`LeafCost`]).
const TRAVERSAL_COST: f32 = 2.0;

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `indices`; interior: index of the right child.
    offset: u32,
    /// Leaf: number of primitives (> 0); interior: 0.
    count: u32,
}

/// A traversal stack of `N` entries ([`unpack`]), left unwritten when a query sets it up:
/// a query reads only the entries below its stack pointer, which its pushes wrote, and zeroing
/// the whole stack for every ray would cost the small scenes' queries a few percent.
type Stack<const N: usize> = [MaybeUninit<u64>; N];

/// Entries of the traversal stack: a visit pops one entry and pushes at most `WIDTH - 1` more,
/// once per level of the wide tree, which is no deeper than the binary one.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;
const STACK8: usize = (WIDTH8 - 1) * MAX_DEPTH + 1;

/// Levels of a wide tree that a query walks with the small stack [`SMALL_STACK`]
/// ([`SMALL_STACK8`]): a stack is set up for every ray, and when it was zeroed 1.5 kB of it
/// showed in the profile of small scenes (it is now left unwritten, [`Stack`], and a small
/// stack keeps the ray's working set small).
const SHALLOW: usize = 8;
const SMALL_STACK: usize = (WIDTH - 1) * SHALLOW + 1;
const SMALL_STACK8: usize = (WIDTH8 - 1) * SHALLOW + 1;
/// Levels of an eight-wide tree walked with [`MID_STACK8`] (the million-triangle sphere's
/// has 11), since the full stack of an eight-wide tree is 3.6 kB.
const MID8: usize = 16;
const MID_STACK8: usize = (WIDTH8 - 1) * MID8 + 1;

/// References from which [`Bvh::build`] chooses eight-wide nodes where it can: measured
/// against Embree (book: "Measuring a renderer", "Against Embree, ray for ray"), they made the
/// million-triangle sphere's rays 5 to 12% faster and the fog box's (12 triangles) and the
/// hundred rooms' (7824 references) any-hit rays 4 to 6% slower. Between the two sizes the
/// threshold is a round guess, not a measurement.
pub const EIGHT_WIDE_REFERENCES: usize = 100_000;

/// References from which the build costs a leaf by its blocks ([`LeafCost::PerBlock`]).
/// Measured on the ray sets of the comparison with Embree (book: "Measuring a renderer",
/// "Against Embree, ray for ray"): on the million-triangle sphere it made camera, bounce and
/// shadow rays 8 to 15, 9 to 10 and 17 to 25% faster and the hierarchy 37% smaller; on the
/// hundred rooms (7824 references) it made them 11 to 25% slower, since a leaf of several walls
/// spans the room the rays start in. Between the two sizes the threshold is a round guess, not
/// a measurement.
pub const BLOCK_COST_REFERENCES: usize = 100_000;

/// What the SAH counts as the cost of a leaf of `n` references.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafCost {
    /// `n` tests: more references in a leaf always cost more.
    PerReference,
    /// `ceil(n / LANES)` tests, one per block of [`leaf::LANES`] references, as the leaves are
    /// tested: a second reference in a block is nearly free, so leaves fill their blocks.
    PerBlock,
}

impl LeafCost {
    /// Per block in trees of at least [`BLOCK_COST_REFERENCES`] references.
    pub fn for_references(references: usize) -> Self {
        if references >= BLOCK_COST_REFERENCES {
            LeafCost::PerBlock
        } else {
            LeafCost::PerReference
        }
    }

    #[inline]
    fn of(self, n: usize) -> f32 {
        match self {
            LeafCost::PerReference => n as f32,
            LeafCost::PerBlock => n.div_ceil(leaf::LANES) as f32,
        }
    }
}

/// [`Bvh::sah_cost`]: the node and leaf terms (Embree's "getAABBNodes" and "leaves" rows,
/// whose sum is its "total"), and the leaves and blocks counted.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SahCost {
    pub nodes: f64,
    pub leaves: f64,
    pub leaf_count: usize,
    pub block_count: usize,
}

/// Children per node of the tree traversal walks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Width {
    /// [`Node4`], four-lane SSE (or the target's four-lane) operations.
    Four,
    /// [`Node8`], eight-lane AVX2 operations.
    Eight,
}

impl Width {
    /// Eight where the processor running this has AVX2 (detected at run time), four elsewhere.
    pub fn native() -> Width {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Width::Eight;
        }
        Width::Four
    }
}

/// The wide tree traversal walks.
#[derive(Clone, Debug)]
enum Nodes {
    Four(Pages<Node4>),
    /// Built only where [`Width::native`] is [`Width::Eight`]: its traversal is compiled for
    /// AVX2.
    Eight(Pages<Node8>),
}

impl Default for Nodes {
    fn default() -> Self {
        Nodes::Four(Pages::default())
    }
}

/// What an any-hit query found along a ray ([`Bvh::passage`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Passage {
    /// A primitive that blocks lies in (0, t_max).
    Blocked,
    /// None blocks, but at least one that does not (a null boundary) lies there.
    Crossing,
    /// No primitive of the tree lies there.
    Clear,
}

/// What a query asks, shared by the traversals of both widths.
struct Query<'a> {
    prims: &'a [Primitive],
    /// Closest hit: which primitives win ties (`opaque`); any hit: which block (`blocks`).
    flags: &'a [bool],
    ray: &'a Ray,
    t_min: f32,
    t_max: f32,
}

/// The hierarchy over a slice of primitives (the primitives are not owned): the four- or
/// eight-wide tree traversal walks (`geometry::wide`, [`Width`]) with its leaves' blocks
/// (`geometry::leaf`), which copy the leaves' triangles. The binary tree of the build ([`Tree`]) is collapsed into it
/// and dropped; what is kept of it is its root's box and its figures for statistics.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    wide: Nodes,
    /// The leaves of `wide`, each a run of blocks its slot names by the first.
    blocks: Pages<Block>,
    /// The lanes of the blocks of quads.
    quads: Pages<QuadLanes>,
    /// Whether a block holds triangles: queries of a tree without set up no
    /// [`TriangleRay`](leaf::TriangleRay), whose division and splats showed as 3% of the path
    /// tracer's time on the fog box's quads.
    triangles: bool,
    /// Levels of the wide tree (which stack size its queries need).
    wide_depth: usize,
    /// The binary tree's root box, depth, nodes and references ([`Bvh::bounds`],
    /// [`Bvh::depth`], [`Bvh::node_count`], [`Bvh::reference_count`]).
    bounds: Aabb,
    depth: usize,
    node_count: usize,
    reference_count: usize,
}

/// The binary tree of the SAH build, flattened depth-first (the left child follows its
/// parent). The four-wide tree is collapsed from it and its leaves' index lists are laid out
/// as blocks; then it is dropped: its nodes and indices (about 36 bytes a reference) are not
/// read by queries.
struct Tree {
    nodes: Vec<Node>,
    indices: Vec<u32>,
    /// Whether the build may end a branch of up to `4 * MAX_LEAF` items in one leaf where the
    /// SAH prefers it: not in a scene of that few references, which is split to leaves of
    /// [`MAX_LEAF`]. The SAH counts rays that enter a node from outside, so it finds that a
    /// box of walls is best tested whole; but the rays of such a scene start inside it, and a
    /// segment between two of its points enters only the flat boxes of the walls it reaches.
    sah_leaves: bool,
    /// How the SAH costs a leaf: per block in large trees ([`BLOCK_COST_REFERENCES`]).
    leaf_cost: LeafCost,
}

impl Binary for Tree {
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

/// The farthest distance a hit may have and still compete in the tie-break with a hit at `t`.
#[inline]
pub fn tie_reach(t: f32) -> f32 {
    t * (1.0 + TIE_EPSILON) + TIE_EPSILON
}

impl Bvh {
    /// Builds the hierarchy (O(n log n)) over the references of [`split_references`].
    pub fn build(prims: &[Primitive]) -> Self {
        Self::build_over(prims, |_| true)
    }

    /// Builds the hierarchy over the primitives `keep` accepts; queries never see the others
    /// (indices still refer to the whole slice).
    /// Eight-wide nodes where the processor has AVX2 and the tree has at least
    /// [`EIGHT_WIDE_REFERENCES`] references, four-wide ones otherwise.
    pub fn build_over(prims: &[Primitive], keep: impl Fn(usize) -> bool) -> Self {
        Self::build_choosing(prims, keep, |references| {
            let width = if references >= EIGHT_WIDE_REFERENCES {
                Width::native()
            } else {
                Width::Four
            };
            (width, LeafCost::for_references(references))
        })
    }

    /// [`Bvh::build_over`] with nodes of `width` children whatever the tree's size;
    /// [`Width::Eight`] where the processor has no AVX2 builds [`Width::Four`].
    pub fn build_with(prims: &[Primitive], keep: impl Fn(usize) -> bool, width: Width) -> Self {
        Self::build_choosing(prims, keep, |n| (width, LeafCost::for_references(n)))
    }

    /// [`Bvh::build_with`] with leaves costed by `leaf_cost` whatever the tree's size.
    pub fn build_costing(
        prims: &[Primitive],
        keep: impl Fn(usize) -> bool,
        width: Width,
        leaf_cost: LeafCost,
    ) -> Self {
        Self::build_choosing(prims, keep, |_| (width, leaf_cost))
    }

    /// The build, the width of its nodes and the cost of its leaves chosen by `choose` from
    /// the number of references.
    fn build_choosing(
        prims: &[Primitive],
        keep: impl Fn(usize) -> bool,
        choose: impl FnOnce(usize) -> (Width, LeafCost),
    ) -> Self {
        let mut items = split_references(prims, keep);
        if items.is_empty() {
            return Bvh::default();
        }
        let (width, leaf_cost) = choose(items.len());
        let mut tree = Tree {
            nodes: Vec::with_capacity(2 * items.len()),
            indices: Vec::with_capacity(items.len()),
            sah_leaves: items.len() > 4 * MAX_LEAF,
            leaf_cost,
        };
        let mut leaf_of = vec![u32::MAX; prims.len()];
        tree.build_recursive(&mut items, 1, &mut leaf_of);
        drop((items, leaf_of));
        let (wide, wide_depth, (blocks, quads)) = match (width, Width::native()) {
            (Width::Eight, Width::Eight) => {
                let (nodes, depth, blocks) = tree.collapse(prims);
                (Nodes::Eight(Pages::new(&nodes)), depth, blocks)
            }
            _ => {
                let (nodes, depth, blocks) = tree.collapse(prims);
                (Nodes::Four(Pages::new(&nodes)), depth, blocks)
            }
        };
        let (blocks, quads) = (Pages::new(&blocks), Pages::new(&quads));
        Bvh {
            wide_depth,
            triangles: blocks.iter().any(|b| b.kind == leaf::Kind::Triangles),
            wide,
            blocks,
            quads,
            bounds: tree.nodes[0].bounds,
            depth: tree.depth(0),
            node_count: tree.nodes.len(),
            reference_count: tree.indices.len(),
        }
    }

    /// The rays of the lane tests, each set up where the tree has blocks it reads.
    #[inline]
    fn lane_rays(&self, ray: &Ray) -> LaneRays {
        LaneRays::new(ray, self.triangles, !self.quads.is_empty())
    }

    /// Calls `visit` on the blocks of the leaf whose first block is `first` until it returns
    /// true (a query that is done); returns whether it did.
    #[inline]
    fn leaf(&self, first: usize, mut visit: impl FnMut(&Block) -> bool) -> bool {
        for block in &self.blocks[first..] {
            if visit(block) {
                return true;
            }
            if block.last {
                break;
            }
        }
        false
    }

    /// Number of nodes of the binary tree of the build (for statistics).
    pub fn node_count(&self) -> usize {
        self.node_count
    }

    /// Number of primitive references in the leaves: more than the primitives where large ones
    /// were split ([`split_references`]).
    pub fn reference_count(&self) -> usize {
        self.reference_count
    }

    /// Bytes the hierarchy holds: its four-wide nodes, leaf blocks and quad lanes (the render's memory
    /// estimate, `render::memory`).
    pub fn memory_bytes(&self) -> usize {
        let nodes = match &self.wide {
            Nodes::Four(n) => std::mem::size_of_val::<[Node4]>(n),
            Nodes::Eight(n) => std::mem::size_of_val::<[Node8]>(n),
        };
        nodes
            + std::mem::size_of_val::<[Block]>(&self.blocks)
            + std::mem::size_of_val::<[QuadLanes]>(&self.quads)
    }

    /// The surface area heuristic's cost of the wide tree in the units Embree reports for its
    /// own (`verbose=2`): each node and each leaf block counted once, weighted by the surface
    /// area of its box over the root's; for rays that cross the root's box uniformly (in the
    /// sense of the SAH), the expected numbers of node and block tests if none stopped early.
    pub fn sah_cost(&self) -> SahCost {
        let mut cost = SahCost::default();
        let root = f64::from(self.bounds.surface_area());
        if root > 0.0 {
            match &self.wide {
                Nodes::Four(n) => self.add_sah(n, 0, root, &mut cost),
                Nodes::Eight(n) => self.add_sah(n, 0, root, &mut cost),
            }
            cost.nodes /= root;
            cost.leaves /= root;
        }
        cost
    }

    /// Adds node `i` (whose box has surface area `area`) and everything under it to `cost`.
    fn add_sah<W: Wide>(&self, nodes: &[W], i: usize, area: f64, cost: &mut SahCost) {
        cost.nodes += area;
        for k in (0..W::WIDTH).filter(|&k| nodes[i].has(k)) {
            let child = f64::from(nodes[i].child_bounds(k).surface_area());
            match nodes[i].slot(k).child() {
                Child::Node(n) => self.add_sah(nodes, n, child, cost),
                Child::Leaf(first) => {
                    let mut blocks = 0;
                    self.leaf(first, |_| {
                        blocks += 1;
                        false
                    });
                    cost.leaves += child * f64::from(blocks);
                    cost.leaf_count += 1;
                    cost.block_count += blocks as usize;
                }
            }
        }
    }

    /// Children per node of the tree traversal walks.
    pub fn width(&self) -> Width {
        match self.wide {
            Nodes::Four(_) => Width::Four,
            Nodes::Eight(_) => Width::Eight,
        }
    }

    /// Number of nodes of the wide tree traversal walks.
    pub fn wide_node_count(&self) -> usize {
        match &self.wide {
            Nodes::Four(n) => n.len(),
            Nodes::Eight(n) => n.len(),
        }
    }

    /// Depth of the binary tree's deepest leaf (the root alone has depth 1; no tree: 0).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Bounds of everything.
    pub fn bounds(&self) -> Aabb {
        self.bounds
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
    /// Traversal tests a node's children together, stacks those the ray enters with their
    /// entry distances, the nearest on top, and checks each distance again when it is popped:
    /// a subtree the best hit so far has moved out of reach is dropped without touching its
    /// node.
    #[inline]
    pub fn intersect_range(
        &self,
        prims: &[Primitive],
        opaque: &[bool],
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let q = Query {
            prims,
            flags: opaque,
            ray,
            t_min,
            t_max,
        };
        let shallow = self.wide_depth <= SHALLOW;
        match &self.wide {
            Nodes::Four(n) if shallow => self.closest4::<SMALL_STACK>(n, &q),
            Nodes::Four(n) => self.closest4::<STACK>(n, &q),
            #[cfg(not(target_arch = "x86_64"))]
            Nodes::Eight(_) => unreachable!("eight-wide nodes are built on x86-64 only"),
            #[cfg(target_arch = "x86_64")]
            Nodes::Eight(n) => {
                // SAFETY: an eight-wide tree is built only where `Width::native` detected AVX2 on
                // this processor (`Bvh::build_with`), so its AVX2 code runs where AVX2 is.
                unsafe { self.closest8(n, &q) }
            }
        }
    }

    /// [`Bvh::closest`] on the four-wide tree with a stack of `N` entries.
    fn closest4<const N: usize>(&self, nodes: &[Node4], q: &Query) -> Option<Hit> {
        let lanes = RayLanes::new(q.ray.o, q.ray.d.recip());
        self.closest::<_, N>(nodes, q, |node: &Node4, limit| {
            node.intersect(&lanes, limit)
        })
    }

    /// [`Bvh::closest`] on the eight-wide tree, compiled for AVX2 so that its node tests run as
    /// eight-lane instructions.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn closest8(&self, nodes: &[Node8], q: &Query) -> Option<Hit> {
        let lanes = RayLanes8::new(q.ray.o, q.ray.d.recip());
        // SAFETY: this function runs only where the processor has AVX2
        let test = |node: &Node8, limit| unsafe { node.intersect_avx2(&lanes, limit) };
        if self.wide_depth <= SHALLOW {
            self.closest::<_, SMALL_STACK8>(nodes, q, test)
        } else if self.wide_depth <= MID8 {
            self.closest::<_, MID_STACK8>(nodes, q, test)
        } else {
            self.closest::<_, STACK8>(nodes, q, test)
        }
    }

    /// The closest-hit traversal of `nodes` with a stack of `N` entries (enough for the
    /// tree's depth), `test` the ray's slab test of a node's children before a limit.
    #[inline(always)]
    fn closest<W: Wide, const N: usize>(
        &self,
        nodes: &[W],
        q: &Query,
        test: impl Fn(&W, f32) -> (u32, W::Near),
    ) -> Option<Hit> {
        let (prims, ray, t_max) = (q.prims, q.ray, q.t_max);
        // hits this far past the best one still compete in the tie-break
        let reach = |t_best: f32| tie_reach(t_best).min(t_max);
        // no separate test of the root's box: the top node's test of its children rejects a
        // ray that misses the scene at the same cost
        if nodes.is_empty() {
            return None;
        }
        let rays = self.lane_rays(ray);
        let query = LeafQuery {
            prims,
            opaque: q.flags,
            ray,
            quads: &self.quads,
            rays: &rays,
            t_min: q.t_min,
            t_max,
            reach: &reach,
        };
        let mut best: Option<Best> = None;
        let mut stack: Stack<N> = [const { MaybeUninit::uninit() }; N];
        let mut sp = 0usize;
        let mut child = Child::Node(0);
        loop {
            match child {
                Child::Leaf(first) => {
                    self.leaf(first, |block| {
                        query.block(block, &mut best);
                        false
                    });
                }
                Child::Node(i) => {
                    let limit = reach(best.map_or(t_max, |b| b.t));
                    let nearest;
                    let node = &nodes[i];
                    (sp, nearest) = push_farther(&mut stack, sp, node, test(node, limit));
                    if let Some(slot) = nearest {
                        child = slot.child();
                        continue;
                    }
                }
            }
            // the next stacked subtree the ray still enters before the best hit's reach (with
            // the slack of the box test)
            loop {
                if sp == 0 {
                    return best.map(|b| b.hit(prims));
                }
                sp -= 1;
                // SAFETY: entries below `sp` were written by the pushes (`Stack`)
                let (next, t_near) = unpack(unsafe { stack[sp].assume_init() });
                if t_near <= reach(best.map_or(t_max, |b| b.t)) * 1.000_000_4 {
                    child = next.child();
                    break;
                }
            }
        }
    }

    /// Any hit with t in (0, t_max) among primitives for which `blocks` is true: on four-wide
    /// nodes the nearer children entered first as in [`Bvh::intersect_range`], on eight-wide
    /// ones in slot order ([`push_unsorted`]).
    #[inline]
    pub fn occluded(&self, prims: &[Primitive], blocks: &[bool], ray: &Ray, t_max: f32) -> bool {
        self.any_hit::<false>(prims, blocks, ray, t_max, &mut false)
    }

    /// [`Bvh::occluded`] that also tells, when nothing blocks the ray, whether it passes any
    /// primitive for which `blocks` is false (a null boundary) in (0, t_max): the same
    /// traversal, which then cannot stop early for such a primitive but visits no more nodes.
    /// A shadow ray with [`Passage::Clear`] needs no query of the boundaries to cut it into
    /// medium segments: it has one.
    #[inline]
    pub fn passage(&self, prims: &[Primitive], blocks: &[bool], ray: &Ray, t_max: f32) -> Passage {
        let mut crossed = false;
        if self.any_hit::<true>(prims, blocks, ray, t_max, &mut crossed) {
            Passage::Blocked
        } else if crossed {
            Passage::Crossing
        } else {
            Passage::Clear
        }
    }

    /// The any-hit query on this tree's nodes; with `CROSS`, `crossed` is set when a hit
    /// primitive does not block.
    #[inline]
    fn any_hit<const CROSS: bool>(
        &self,
        prims: &[Primitive],
        blocks: &[bool],
        ray: &Ray,
        t_max: f32,
        crossed: &mut bool,
    ) -> bool {
        let q = Query {
            prims,
            flags: blocks,
            ray,
            t_min: 0.0,
            t_max,
        };
        let shallow = self.wide_depth <= SHALLOW;
        match &self.wide {
            Nodes::Four(n) if shallow => self.any4::<SMALL_STACK, CROSS>(n, &q, crossed),
            Nodes::Four(n) => self.any4::<STACK, CROSS>(n, &q, crossed),
            #[cfg(not(target_arch = "x86_64"))]
            Nodes::Eight(_) => unreachable!("eight-wide nodes are built on x86-64 only"),
            #[cfg(target_arch = "x86_64")]
            Nodes::Eight(n) => {
                // SAFETY: an eight-wide tree is built only where `Width::native` detected AVX2 on
                // this processor (`Bvh::build_with`), so its AVX2 code runs where AVX2 is.
                unsafe { self.any8::<CROSS>(n, &q, crossed) }
            }
        }
    }

    /// [`Bvh::any`] on the four-wide tree with a stack of `N` entries.
    fn any4<const N: usize, const CROSS: bool>(
        &self,
        nodes: &[Node4],
        q: &Query,
        crossed: &mut bool,
    ) -> bool {
        let lanes = RayLanes::new(q.ray.o, q.ray.d.recip());
        let test = |node: &Node4, limit| node.intersect(&lanes, limit);
        self.any::<_, N, CROSS>(nodes, q, test, crossed)
    }

    /// [`Bvh::any`] on the eight-wide tree, compiled for AVX2 ([`Bvh::closest8`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn any8<const CROSS: bool>(&self, nodes: &[Node8], q: &Query, crossed: &mut bool) -> bool {
        let lanes = RayLanes8::new(q.ray.o, q.ray.d.recip());
        // SAFETY: this function runs only where the processor has AVX2
        let test = |node: &Node8, limit| unsafe { node.intersect_avx2(&lanes, limit) };
        if self.wide_depth <= SHALLOW {
            self.any::<_, SMALL_STACK8, CROSS>(nodes, q, test, crossed)
        } else if self.wide_depth <= MID8 {
            self.any::<_, MID_STACK8, CROSS>(nodes, q, test, crossed)
        } else {
            self.any::<_, STACK8, CROSS>(nodes, q, test, crossed)
        }
    }

    /// The any-hit traversal of `nodes` with a stack of `N` entries (enough for the tree's
    /// depth), `test` as in [`Bvh::closest`]; with `CROSS` it notes in `crossed` a hit
    /// primitive that does not block ([`Bvh::passage`]).
    #[inline(always)]
    fn any<W: Wide, const N: usize, const CROSS: bool>(
        &self,
        nodes: &[W],
        q: &Query,
        test: impl Fn(&W, f32) -> (u32, W::Near),
        crossed: &mut bool,
    ) -> bool {
        let (prims, blocks, ray, t_max) = (q.prims, q.flags, q.ray, q.t_max);
        if nodes.is_empty() {
            return false;
        }
        let rays = self.lane_rays(ray);
        let mut stack: Stack<N> = [const { MaybeUninit::uninit() }; N];
        let mut sp = 0usize;
        let mut child = Child::Node(0);
        loop {
            match child {
                Child::Leaf(first) => {
                    let lanes = (&self.quads[..], &rays);
                    let occludes = |b: &Block| {
                        block_occludes::<CROSS>(b, (prims, blocks), ray, lanes, t_max, crossed)
                    };
                    if self.leaf(first, occludes) {
                        return true;
                    }
                }
                Child::Node(i) => {
                    let nearest;
                    let node = &nodes[i];
                    let hit = test(node, t_max);
                    // unsorted pays on eight-wide nodes only (book: "Measuring a renderer",
                    // "Against Embree, ray for ray")
                    (sp, nearest) = if W::WIDTH == WIDTH8 {
                        push_unsorted(&mut stack, sp, node, hit.0)
                    } else {
                        push_farther(&mut stack, sp, node, hit)
                    };
                    if let Some(slot) = nearest {
                        child = slot.child();
                        continue;
                    }
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            // SAFETY: as in `Bvh::closest`
            child = unpack(unsafe { stack[sp].assume_init() }).0.child();
        }
    }
}

impl Tree {
    /// The wide tree of this one ([`collapse`]), its levels, and its leaves' blocks with
    /// their quad lanes.
    fn collapse<W: Wide>(
        &self,
        prims: &[Primitive],
    ) -> (Vec<W>, usize, (Vec<Block>, Vec<QuadLanes>)) {
        let mut wide = collapse(self, 0);
        let blocks = self.lay_out_leaves(&mut wide, prims);
        let depth = wide_depth(&wide, 0);
        (wide, depth, blocks)
    }

    /// Renames every leaf slot of the wide tree `wide` from its binary node to its first
    /// block, laying the blocks out in the order the slots come in; returns the blocks and
    /// the quad lanes.
    fn lay_out_leaves<W: Wide>(
        &self,
        wide: &mut [W],
        prims: &[Primitive],
    ) -> (Vec<Block>, Vec<QuadLanes>) {
        let mut blocks = Vec::with_capacity(self.indices.len().div_ceil(2));
        let mut quads = Vec::new();
        for node in wide.iter_mut() {
            for k in 0..W::WIDTH {
                if !node.has(k) {
                    continue;
                }
                if let Child::Leaf(n) = node.slot(k).child() {
                    let ids = self.leaf_indices(n);
                    let first = leaf::lay_out(ids, prims, &mut blocks, &mut quads);
                    node.set_slot(k, Slot::leaf(first as usize));
                }
            }
        }
        (blocks, quads)
    }

    /// The primitive indices of leaf `leaf`.
    fn leaf_indices(&self, leaf: usize) -> &[u32] {
        let n = &self.nodes[leaf];
        &self.indices[n.offset as usize..(n.offset + n.count) as usize]
    }

    /// Depth of the deepest leaf under node `i` (a leaf: 1).
    fn depth(&self, i: usize) -> usize {
        match self.children(i) {
            None => 1,
            Some((l, r)) => 1 + self.depth(l).max(self.depth(r)),
        }
    }

    /// `leaf_of[i]` is the last leaf primitive `i` was put in: a leaf holding two references
    /// of one primitive lists it once.
    fn build_recursive(
        &mut self,
        items: &mut [BuildItem],
        depth: usize,
        leaf_of: &mut [u32],
    ) -> usize {
        let bounds = items.iter().fold(Aabb::EMPTY, |b, it| b.union(it.bounds));
        let node_index = self.nodes.len();
        self.nodes.push(Node {
            bounds,
            offset: 0,
            count: 0,
        });
        let make_leaf = |tree: &mut Tree, items: &mut [BuildItem], leaf_of: &mut [u32]| {
            let first = tree.indices.len();
            for it in items.iter() {
                if std::mem::replace(&mut leaf_of[it.index as usize], node_index as u32)
                    != node_index as u32
                {
                    tree.indices.push(it.index);
                }
            }
            tree.nodes[node_index].offset = first as u32;
            tree.nodes[node_index].count = (tree.indices.len() - first) as u32;
            node_index
        };
        if items.len() <= MAX_LEAF || depth >= MAX_DEPTH {
            return make_leaf(self, items, leaf_of);
        }
        let cb = items.iter().fold(Aabb::EMPTY, |b, it| b.grow(it.centroid));
        let extent = cb.extent();
        let widest = extent.max_position();
        if extent[widest] <= 0.0 {
            // all centroids coincide: split in the middle of the list
            let mid = items.len() / 2;
            return self.split(node_index, items, mid, depth, leaf_of);
        }
        // the cheapest binned SAH split over the axes along which the centroids spread
        let mut best = Split {
            cost: f32::INFINITY,
            axis: widest,
            bin: 0,
        };
        for axis in (0..3).filter(|&a| extent[a] > 0.0) {
            let split = sah_split(items, &cb, axis, self.leaf_cost);
            if split.cost < best.cost {
                best = split;
            }
        }
        let leaf_cost = self.leaf_cost.of(items.len());
        let split_cost = TRAVERSAL_COST + best.cost / bounds.surface_area().max(f32::MIN_POSITIVE);
        if best.cost.is_infinite()
            || (split_cost >= leaf_cost && items.len() <= 4 * MAX_LEAF && self.sah_leaves)
        {
            if best.cost.is_infinite() {
                let mid = items.len() / 2;
                items.sort_by(|a, b| a.centroid[widest].total_cmp(&b.centroid[widest]));
                return self.split(node_index, items, mid, depth, leaf_of);
            }
            return make_leaf(self, items, leaf_of);
        }
        let mut mid = 0;
        for i in 0..items.len() {
            if bin_of(&cb, best.axis, items[i].centroid) < best.bin {
                items.swap(i, mid);
                mid += 1;
            }
        }
        self.split(node_index, items, mid, depth, leaf_of)
    }

    fn split(
        &mut self,
        node_index: usize,
        items: &mut [BuildItem],
        mid: usize,
        depth: usize,
        leaf_of: &mut [u32],
    ) -> usize {
        let (left, right) = items.split_at_mut(mid);
        self.build_recursive(left, depth + 1, leaf_of);
        let r = self.build_recursive(right, depth + 1, leaf_of);
        self.nodes[node_index].offset = r as u32;
        self.nodes[node_index].count = 0;
        node_index
    }
}

/// A candidate split of the build: the items whose centroid falls in a bin below `bin` along
/// `axis` go left; `cost` is the surface area heuristic's, without the constant terms.
struct Split {
    cost: f32,
    axis: usize,
    bin: usize,
}

/// The bin of centroid `c` along `axis`, the centroids' bounds `cb` cut into [`BINS`] slabs.
#[inline]
fn bin_of(cb: &Aabb, axis: usize, c: Vec3) -> usize {
    let scale = BINS as f32 / (cb.max[axis] - cb.min[axis]);
    (((c[axis] - cb.min[axis]) * scale) as usize).min(BINS - 1)
}

// ANCHOR: sah
/// The binned SAH's best split along `axis` (Wald 2007): the items binned by centroid, each
/// plane between bins costed as left area x left cost + right area x right cost, a side's
/// cost that of a leaf of its items (`leaf_cost`).
fn sah_split(items: &[BuildItem], cb: &Aabb, axis: usize, leaf_cost: LeafCost) -> Split {
    let mut bin_bounds = [Aabb::EMPTY; BINS];
    let mut bin_count = [0usize; BINS];
    for it in items.iter() {
        let b = bin_of(cb, axis, it.centroid);
        bin_bounds[b] = bin_bounds[b].union(it.bounds);
        bin_count[b] += 1;
    }
    let mut right_area = [0.0f32; BINS];
    let mut right_count = [0usize; BINS];
    let (mut acc_b, mut acc_n) = (Aabb::EMPTY, 0usize);
    for i in (1..BINS).rev() {
        acc_b = acc_b.union(bin_bounds[i]);
        acc_n += bin_count[i];
        right_area[i] = acc_b.surface_area();
        right_count[i] = acc_n;
    }
    let mut best = Split {
        cost: f32::INFINITY,
        axis,
        bin: 0,
    };
    let (mut acc_b, mut acc_n) = (Aabb::EMPTY, 0usize);
    for i in 1..BINS {
        acc_b = acc_b.union(bin_bounds[i - 1]);
        acc_n += bin_count[i - 1];
        let cost = acc_b.surface_area() * leaf_cost.of(acc_n)
            + right_area[i] * leaf_cost.of(right_count[i]);
        if acc_n > 0 && right_count[i] > 0 && cost < best.cost {
            best.cost = cost;
            best.bin = i;
        }
    }
    best
}
// ANCHOR_END: sah

// ANCHOR: split_references
/// The build's references to the primitives: one per primitive, except that a primitive whose
/// box is large against the others' is referenced once per piece of its box, cut in halves
/// across the longest side until each piece is small (early split clipping, Ernst and Greiner
/// 2007, sec. 3). A floor spanning a hundred rooms then sits in every room's subtree with that
/// room's piece of its box, instead of dragging one box over the whole scene high in the tree,
/// which every ray would enter. A piece's box is the primitive's box clipped to the piece:
/// conservative, tight for the axis-aligned quads this is for. The pieces share their cut
/// planes exactly, so a ray that enters the whole box at a point of the primitive enters a
/// piece holding that point, and queries find the same hits (one primitive may be tested twice,
/// which changes no result).
fn split_references(prims: &[Primitive], keep: impl Fn(usize) -> bool) -> Vec<BuildItem> {
    let boxes: Vec<(usize, Aabb)> = (0..prims.len())
        .filter(|&i| keep(i))
        .map(|i| (i, prims[i].bounds()))
        .collect();
    let mean = boxes.iter().map(|b| b.1.surface_area()).sum::<f32>() / boxes.len().max(1) as f32;
    let small = SPLIT_AREA * mean;
    // at most this many references more than primitives: bounded memory whatever the scene
    let mut budget = SPLIT_BUDGET * boxes.len();
    let mut items = Vec::with_capacity(prims.len());
    let mut pieces = Vec::new();
    for &(i, b) in &boxes {
        pieces.clear();
        pieces.push(b);
        let mut k = 0;
        // piece k is halved until small, then k moves on to the halves pushed behind it
        while k < pieces.len() {
            let piece = pieces[k];
            match halves(piece).filter(|_| piece.surface_area() > small && budget > 0) {
                Some((lo, hi)) => {
                    pieces[k] = lo;
                    pieces.push(hi);
                    budget -= 1;
                }
                None => k += 1,
            }
        }
        items.extend(pieces.iter().map(|&p| BuildItem {
            bounds: p,
            centroid: p.centroid(),
            index: i as u32,
        }));
    }
    items
}
// ANCHOR_END: split_references

/// `b` cut in two across its longest side, at a plane both halves share; `None` when that
/// side is too short to cut in floating point.
fn halves(b: Aabb) -> Option<(Aabb, Aabb)> {
    let axis = b.extent().max_position();
    let mid = 0.5 * (b.min[axis] + b.max[axis]);
    if !(mid > b.min[axis] && mid < b.max[axis]) {
        return None;
    }
    let (mut lo, mut hi) = (b, b);
    lo.max[axis] = mid;
    hi.min[axis] = mid;
    Some((lo, hi))
}

/// Pushes the children of `node` the ray enters (`enters`, at distances `near`, the node's slab
/// test before `limit`) onto `stack` above `sp`, the
/// farthest first, except the nearest, which is returned to be visited next without a trip
/// through the stack (it would be popped next, and it passes the pop's distance test, since
/// it was entered before `limit`); returns the new stack pointer. At most `W::WIDTH - 1`
/// entries more than were popped to get here: cannot overflow a stack of [`STACK`]
/// ([`STACK8`]) entries, nor one of the smaller stacks in a tree of the levels they are for.
/// Always inlined: in the AVX2 traversal ([`Bvh::closest8`]) its eight-lane slab test is then
/// compiled with AVX2 (out of line it was two four-lane halves, slower than four-wide nodes).
#[inline(always)]
fn push_farther<W: Wide, const N: usize>(
    stack: &mut Stack<N>,
    mut sp: usize,
    node: &W,
    (enters, near): (u32, W::Near),
) -> (usize, Option<Slot>) {
    let mut entered = [(0.0f32, Slot(0)); WIDTH8];
    let mut n = 0;
    for k in 0..W::WIDTH {
        if enters & (1 << k) != 0 {
            let t = near[k];
            // insertion by decreasing distance; of equal ones the later child is popped first
            let mut j = n;
            while j > 0 && entered[j - 1].0 < t {
                entered[j] = entered[j - 1];
                j -= 1;
            }
            entered[j] = (t, node.slot(k));
            n += 1;
        }
    }
    let Some((&(_, nearest), farther)) = entered[..n].split_last() else {
        return (sp, None);
    };
    for &(t, slot) in farther {
        stack[sp] = MaybeUninit::new(u64::from(slot.0) | (u64::from(t.to_bits()) << 32));
        sp += 1;
    }
    (sp, Some(nearest))
}

/// [`push_farther`] without the sort, for any-hit queries, whose answer does not depend on
/// the order: the lowest entered child is visited next, the others are stacked.
#[inline(always)]
fn push_unsorted<W: Wide, const N: usize>(
    stack: &mut Stack<N>,
    mut sp: usize,
    node: &W,
    enters: u32,
) -> (usize, Option<Slot>) {
    if enters == 0 {
        return (sp, None);
    }
    let first = enters.trailing_zeros() as usize;
    let mut rest = enters & (enters - 1);
    while rest != 0 {
        let k = rest.trailing_zeros() as usize;
        stack[sp] = MaybeUninit::new(u64::from(node.slot(k).0));
        sp += 1;
        rest &= rest - 1;
    }
    (sp, Some(node.slot(first)))
}

/// Levels of the wide tree under node `i` (a node whose children are all leaves: 1).
fn wide_depth<W: Wide>(wide: &[W], i: usize) -> usize {
    let below = (0..W::WIDTH)
        .filter(|&k| wide[i].has(k))
        .filter_map(|k| match wide[i].slot(k).child() {
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

/// The best hit of a closest-hit query so far: a triangle's or a quad's as its coordinates (its
/// point is computed once, for the hit returned), another primitive's with its point and normal.
#[derive(Clone, Copy)]
struct Best {
    t: f32,
    prim: u32,
    at: At,
}

#[derive(Clone, Copy)]
enum At {
    /// A triangle's barycentrics or a quad's coordinates (a, b) ([`leaf::lane_point`]).
    Lane(f32, f32),
    Point(Vec3, Vec3),
}

impl Best {
    fn hit(self, prims: &[Primitive]) -> Hit {
        let (p, ng) = match self.at {
            At::Point(p, ng) => (p, ng),
            At::Lane(x, y) => leaf::lane_point(&prims[self.prim as usize], x, y),
        };
        Hit {
            t: self.t,
            p,
            ng,
            prim: self.prim,
        }
    }
}

/// What a closest-hit query's leaf visit needs besides the block and the best hit.
struct LeafQuery<'a, R: Fn(f32) -> f32> {
    prims: &'a [Primitive],
    opaque: &'a [bool],
    ray: &'a Ray,
    /// The tree's quad lanes.
    quads: &'a [QuadLanes],
    rays: &'a LaneRays,
    t_min: f32,
    t_max: f32,
    /// The farthest distance a hit may have to compete with the best one at `t`.
    reach: &'a R,
}

impl<R: Fn(f32) -> f32> LeafQuery<'_, R> {
    /// Offers the block's hits to `best` in the leaf's order, each within the reach of the
    /// best hit before it, as the primitives' own tests with that reach as t_max would.
    #[inline]
    fn block(&self, block: &Block, best: &mut Option<Best>) {
        let limit = |best: &Option<Best>| (self.reach)(best.map_or(self.t_max, |b| b.t));
        let lanes = leaf::hits(block, self.quads, self.rays, self.t_min, limit(best));
        if let Some((mut mask, t, x, y)) = lanes {
            // arrays, read at the lane's index by address: a `Vec4` indexed by a lane known
            // only at run time compiled to a jump on the lane, a branch no predictor can guess
            // for diffuse bounces (book: "Against Embree, ray for ray")
            let (t, x, y) = (t.to_array(), x.to_array(), y.to_array());
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if t[k] < limit(best) {
                    let at = At::Lane(x[k], y[k]);
                    self.offer(best, t[k], block.ids[k], at);
                }
            }
        } else {
            for &pi in &block.ids[..block.lanes as usize] {
                let prim = &self.prims[pi as usize];
                if let Some((t, p, ng)) = prim.intersect_range(self.ray, self.t_min, limit(best)) {
                    self.offer(best, t, pi, At::Point(p, ng));
                }
            }
        }
    }

    #[inline]
    fn offer(&self, best: &mut Option<Best>, t: f32, prim: u32, at: At) {
        if best.is_none_or(|b| closer((t, prim), (b.t, b.prim), self.opaque)) {
            if matches!(at, At::Lane(..)) {
                prefetch(&self.prims[prim as usize]);
            }
            *best = Some(Best { t, prim, at });
        }
    }
}

/// Whether a primitive of `block` for which `blocks` is true lies at t in (0, t_max); with
/// `CROSS`, `crossed` is set when one for which it is false does and none blocks.
/// Always inlined, as [`Block::hits`]: out of line it was a call per block of an any-hit
/// query, and the fog box's shadow rays were 2 to 6% slower (book: "Against Embree, ray for
/// ray").
#[inline(always)]
fn block_occludes<const CROSS: bool>(
    block: &Block,
    (prims, blocks): (&[Primitive], &[bool]),
    ray: &Ray,
    (quads, rays): (&[QuadLanes], &LaneRays),
    t_max: f32,
    crossed: &mut bool,
) -> bool {
    let ids = &block.ids[..block.lanes as usize];
    if let Some((mask, t, _, _)) = leaf::hits(block, quads, rays, 0.0, t_max) {
        let mask = mask & t.cmplt(glam::Vec4::splat(t_max)).bitmask();
        // the lanes' flags read only for a block with a hit, and then without a branch per
        // lane (an unused lane repeats lane 0, whose flag it reads)
        mask != 0 && {
            let flags = (0..leaf::LANES).fold(0u32, |f, k| {
                f | (u32::from(blocks[block.ids[k] as usize]) << k)
            });
            let blocked = mask & flags != 0;
            if CROSS && !blocked {
                // the hit lanes are all boundaries
                *crossed = true;
            }
            blocked
        }
    } else {
        ids.iter().any(|&pi| {
            let (block, prim) = (blocks[pi as usize], &prims[pi as usize]);
            // a boundary is tested only while none has been crossed
            let asked = block || (CROSS && !*crossed);
            let hit = asked && prim.intersect(ray, t_max).is_some();
            if CROSS && hit && !block {
                *crossed = true;
            }
            hit && block
        })
    }
}

/// Asks the processor to load the cache line of `value` without waiting for it: the best
/// hit's primitive, read at the end of the query for its point and normal.
#[inline(always)]
fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch only hints the cache; it reads nothing and cannot fault.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

// ANCHOR: tie_break
/// Whether hit `a` (distance, primitive) is the one to keep over `b`: the nearer, except that
/// within [`TIE_EPSILON`] (relative) an opaque primitive wins over a null one; among equals the
/// lower primitive index, so that the result does not depend on the order the hits were found
/// in.
fn closer(a: (f32, u32), b: (f32, u32), opaque: &[bool]) -> bool {
    let ((ta, pa), (tb, pb)) = (a, b);
    let (oa, ob) = (opaque[pa as usize], opaque[pb as usize]);
    let tie = (ta - tb).abs() <= TIE_EPSILON * (1.0 + tb);
    if tie && oa != ob {
        return oa;
    }
    ta < tb || (ta == tb && pa < pb)
}
// ANCHOR_END: tie_break
