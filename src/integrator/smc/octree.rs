//! The 5-D structure: a spatial octree whose leaves hold radiance caches (Pegoraro, Wald,
//! Parker 2008, sec. 4.3-4.4, Fig. 1 c-f).
//!
//! It starts as one node holding a root cache of two cells. Every record is routed to the leaf
//! containing its position (O(depth)) and merged into that leaf's cache. When the refinement
//! criterion is met, the average record count of the cache reaching the refinement threshold
//! (the method's single parameter), the cache's resolution doubles in both coordinates and the
//! node splits into eight children, each receiving a copy whose counters are divided by 32
//! (never to zero). The root may not refine before both its cells have a non-zero pdf
//! coefficient; with inheritance, every pdf of every later leaf is then non-zero, with no
//! clamping.
//!
//! Memory is bounded by a budget: a refinement that would exceed it is not made, refinement
//! stops for good (recorded in [`OctreeStats::budget_reached`]) and the render continues,
//! unbiased, with the structure it has.
//! Book: "SMC: the radiance cache", section "The octree".

use glam::Vec3;

use super::cache::RadianceCache;
use super::estimator::ControlVariate;

/// The deepest level a node may reach: a leaf there holds 2 * 4^MAX_OCTREE_DEPTH cells
/// (33.5 M), about 1 GiB, the default budget; deeper is never affordable.
pub const MAX_OCTREE_DEPTH: u32 = 12;

/// One radiance record: the estimate `radiance` of L arriving at `p` from `wi`, and the phase
/// value that weighted it in f [PWP08 Fig. 2 line 13, `AddRecordToCache(direction, radiance)`].
#[derive(Clone, Copy, Debug)]
pub struct Record {
    pub p: Vec3,
    pub wi: Vec3,
    pub radiance: Vec3,
    pub phase_value: f32,
}

#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
enum Node {
    Leaf { cache: u32 },
    Inner { first_child: u32 },
}

/// The structure's statistics: the columns of [PWP08 Table 1] plus the budget.
#[derive(Clone, Debug, PartialEq)]
pub struct OctreeStats {
    pub threshold: f64,
    pub max_depth: u32,
    pub nodes: usize,
    pub leaves: usize,
    pub cells: usize,
    pub bytes: usize,
    pub budget: usize,
    pub budget_reached: bool,
    /// Records merged so far.
    pub records: u64,
}

impl std::fmt::Display for OctreeStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "smc structure: refinement threshold {}, max depth {}, {} nodes, {} leaves, {} cells, \
             {} bytes ({} of a {} budget), {} records",
            self.threshold,
            self.max_depth,
            self.nodes,
            self.leaves,
            self.cells,
            self.bytes,
            human_bytes(self.bytes),
            human_bytes(self.budget),
            self.records
        )?;
        if self.budget_reached {
            write!(
                f,
                "; memory budget reached: refinement stopped, the render went on (unbiased) \
                 with this structure"
            )?;
        }
        Ok(())
    }
}

/// `bytes` with a binary unit, for the statistics line.
fn human_bytes(bytes: usize) -> String {
    const KIB: f64 = 1024.0;
    let b = bytes as f64;
    if b >= KIB * KIB * KIB {
        format!("{:.2} GiB", b / (KIB * KIB * KIB))
    } else if b >= KIB * KIB {
        format!("{:.1} MiB", b / (KIB * KIB))
    } else {
        format!("{:.1} KiB", b / KIB)
    }
}

/// The spatial octree of radiance caches (serialized whole into a checkpoint: a resumed SMC
/// render continues from the structure the interrupted one had built).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Octree {
    nodes: Vec<Node>,
    caches: Vec<RadianceCache>,
    min: Vec3,
    max: Vec3,
    /// The refinement threshold on the average record count [PWP08 sec. 4.4].
    pub threshold: f64,
    /// Memory budget in bytes.
    pub budget: usize,
    /// The control variate whose g enters the pdf records |f - g|.
    pub cv: ControlVariate,
    bytes: usize,
    budget_reached: bool,
    max_depth: u32,
    records: u64,
}

impl Octree {
    /// One node over the box [min, max] holding the root cache.
    pub fn new(min: Vec3, max: Vec3, threshold: f64, budget: usize, cv: ControlVariate) -> Self {
        let root = RadianceCache::root();
        let bytes = root.bytes() + std::mem::size_of::<Node>();
        Octree {
            nodes: vec![Node::Leaf { cache: 0 }],
            caches: vec![root],
            min,
            max,
            threshold,
            budget,
            cv,
            bytes,
            budget_reached: false,
            max_depth: 0,
            records: 0,
        }
    }

    /// The leaf containing `p` (points outside the box go to the nearest leaf): (node index,
    /// depth, cache index).
    // ANCHOR: lookup
    #[inline]
    fn find(&self, p: Vec3) -> (usize, u32, usize) {
        let (mut lo, mut hi) = (self.min, self.max);
        let mut node = 0usize;
        let mut depth = 0;
        loop {
            match self.nodes[node] {
                Node::Leaf { cache } => return (node, depth, cache as usize),
                Node::Inner { first_child } => {
                    let mid = 0.5 * (lo + hi);
                    let mut octant = 0;
                    for axis in 0..3 {
                        if p[axis] >= mid[axis] {
                            octant |= 1 << axis;
                            lo[axis] = mid[axis];
                        } else {
                            hi[axis] = mid[axis];
                        }
                    }
                    node = first_child as usize + octant;
                    depth += 1;
                }
            }
        }
    }
    // ANCHOR_END: lookup

    /// The cache of the leaf containing `p` [PWP08 Fig. 2 line 4].
    #[inline]
    pub fn cache(&self, p: Vec3) -> &RadianceCache {
        &self.caches[self.find(p).2]
    }

    /// Merges one record into its leaf and refines the leaf if the criterion is met
    /// [PWP08 Fig. 2 lines 12-14].
    // ANCHOR: merge
    pub fn add_record(&mut self, r: &Record) {
        let (node, depth, cache) = self.find(r.p);
        let c = &mut self.caches[cache];
        c.write(r.wi, r.radiance, r.phase_value, self.cv);
        self.records += 1;
        if self.criterion_is_met(depth, cache) {
            self.refine(node, depth, cache);
        }
    }

    /// The refinement criterion: the average record count reaches the threshold, and the root
    /// only once both its cells have a non-zero pdf coefficient.
    fn criterion_is_met(&self, depth: u32, cache: usize) -> bool {
        let c = &self.caches[cache];
        !self.budget_reached
            && depth < MAX_OCTREE_DEPTH
            && c.average_count() >= self.threshold
            && (depth > 0 || c.pdf_is_positive())
    }

    /// Splits a leaf into eight children holding refined copies of its cache, unless the memory
    /// budget would be exceeded (then refinement stops for good).
    fn refine(&mut self, node: usize, depth: u32, cache: usize) {
        let fine_cells = self.caches[cache].grid().refined().cells();
        let added = 8 * RadianceCache::bytes_for(fine_cells) + 8 * std::mem::size_of::<Node>();
        let freed = self.caches[cache].bytes();
        if self.bytes - freed + added > self.budget {
            self.budget_reached = true;
            return;
        }
        let refined = self.caches[cache].refined();
        let first_child = self.nodes.len() as u32;
        for octant in 0..8 {
            let index = if octant == 0 {
                self.caches[cache] = refined.clone();
                cache
            } else {
                self.caches.push(refined.clone());
                self.caches.len() - 1
            };
            self.nodes.push(Node::Leaf {
                cache: index as u32,
            });
        }
        self.nodes[node] = Node::Inner { first_child };
        self.bytes = self.bytes - freed + 8 * refined.bytes() + 8 * std::mem::size_of::<Node>();
        self.max_depth = self.max_depth.max(depth + 1);
    }
    // ANCHOR_END: merge

    /// Whether a structure read back (from a checkpoint) can be used: every child block after
    /// its parent and inside the node array (so a lookup ends), every cache index in range and
    /// every cache's arrays the size of its grid.
    pub fn is_consistent(&self) -> bool {
        let nodes = self.nodes.len();
        let nodes_ok = self.nodes.iter().enumerate().all(|(i, n)| match *n {
            Node::Leaf { cache } => (cache as usize) < self.caches.len(),
            Node::Inner { first_child } => {
                let f = first_child as usize;
                f > i && f + 8 <= nodes
            }
        });
        nodes > 0 && nodes_ok && self.caches.iter().all(RadianceCache::is_consistent)
    }

    /// Every leaf's cache.
    pub fn caches(&self) -> &[RadianceCache] {
        &self.caches
    }

    /// Every leaf's box (min, max) and cache: the spatial subdivision, for drawing it.
    pub fn leaves(&self) -> Vec<(Vec3, Vec3, &RadianceCache)> {
        let mut out = Vec::new();
        let mut stack = vec![(0usize, self.min, self.max)];
        while let Some((node, lo, hi)) = stack.pop() {
            match self.nodes[node] {
                Node::Leaf { cache } => out.push((lo, hi, &self.caches[cache as usize])),
                Node::Inner { first_child } => {
                    let mid = 0.5 * (lo + hi);
                    for octant in 0..8 {
                        let (mut a, mut b) = (lo, hi);
                        for axis in 0..3 {
                            if octant & (1 << axis) != 0 {
                                a[axis] = mid[axis];
                            } else {
                                b[axis] = mid[axis];
                            }
                        }
                        stack.push((first_child as usize + octant, a, b));
                    }
                }
            }
        }
        out
    }

    /// The statistics of [PWP08 Table 1].
    pub fn stats(&self) -> OctreeStats {
        OctreeStats {
            threshold: self.threshold,
            max_depth: self.max_depth,
            nodes: self.nodes.len(),
            leaves: self.caches.len(),
            cells: self.caches.iter().map(|c| c.grid().cells()).sum(),
            bytes: self.bytes,
            budget: self.budget,
            budget_reached: self.budget_reached,
            records: self.records,
        }
    }
}
