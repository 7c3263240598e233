//! What BDPT's connections read from the vertices of a subpath besides the vertices themselves:
//! a vertex's density ratio for the MIS weight, the unit direction to its predecessor and the
//! factor converting a density at it into its predecessor's measure. Every connection through
//! a vertex needs the same three values, so `Bdpt::combine` computes them once per sample
//! ([`Cached`]), while the other callers compute them on the fly (`[Vertex]`): both with the
//! functions below, so a weight rounds the same either way.
//! Book: "Measuring a renderer", "Where the time goes".

use glam::Vec3;

use super::geometry_term::AreaFactor;
use super::Vertex;

/// A density in the MIS ratios: zero (an unset or Dirac density) counts as one (Veach 1997,
/// sec. 10.2: the Dirac factors cancel between the two strategies compared).
#[inline]
pub fn remap(f: f32) -> f32 {
    if f != 0.0 {
        f
    } else {
        1.0
    }
}

/// The ratio p_rev / p_fwd of one vertex, the factor it adds to the weights of the strategies
/// beyond it (Veach 1997, eq. 10.9).
#[inline]
pub fn ratio(v: &Vertex) -> f32 {
    remap(v.pdf_rev) / remap(v.pdf_fwd)
}

/// The unit direction from vertex `i` of `path` to its predecessor, as `Vertex::f_hat` and
/// `Vertex::pdf_dir` compute it from the two positions.
#[inline]
pub fn to_prev(path: &[Vertex], i: usize) -> Vec3 {
    (path[i - 1].p - path[i].p).normalize_or_zero()
}

/// The per-vertex values of one subpath vertex (i > 0; vertex 0 has no predecessor).
#[derive(Clone, Copy, Debug, Default)]
pub struct VertexCache {
    ratio: f32,
    to_prev: Vec3,
    prev_area: AreaFactor,
}

/// Fills `cache` with the values of every vertex of `path`.
pub fn fill(path: &[Vertex], cache: &mut Vec<VertexCache>) {
    cache.clear();
    cache.extend(path.iter().enumerate().map(|(i, v)| {
        if i == 0 {
            VertexCache {
                ratio: ratio(v),
                ..VertexCache::default()
            }
        } else {
            VertexCache {
                ratio: ratio(v),
                to_prev: to_prev(path, i),
                prev_area: AreaFactor::new(v, &path[i - 1]),
            }
        }
    }));
}

/// A subpath as a connection reads it.
pub trait Subpath {
    fn vertices(&self) -> &[Vertex];
    /// [`ratio`] of vertex `i`.
    fn ratio(&self, i: usize) -> f32;
    /// [`to_prev`] of vertex `i` (i > 0).
    fn to_prev(&self, i: usize) -> Vec3;
    /// The conversion of a density at vertex `i` (i > 0) into the measure of vertex i - 1.
    fn prev_area(&self, i: usize) -> AreaFactor;
}

impl Subpath for [Vertex] {
    #[inline]
    fn vertices(&self) -> &[Vertex] {
        self
    }
    #[inline]
    fn ratio(&self, i: usize) -> f32 {
        ratio(&self[i])
    }
    #[inline]
    fn to_prev(&self, i: usize) -> Vec3 {
        to_prev(self, i)
    }
    #[inline]
    fn prev_area(&self, i: usize) -> AreaFactor {
        AreaFactor::new(&self[i], &self[i - 1])
    }
}

/// A subpath with its values computed by [`fill`].
pub struct Cached<'a> {
    pub path: &'a [Vertex],
    pub cache: &'a [VertexCache],
}

impl Subpath for Cached<'_> {
    #[inline]
    fn vertices(&self) -> &[Vertex] {
        self.path
    }
    #[inline]
    fn ratio(&self, i: usize) -> f32 {
        self.cache[i].ratio
    }
    #[inline]
    fn to_prev(&self, i: usize) -> Vec3 {
        self.cache[i].to_prev
    }
    #[inline]
    fn prev_area(&self, i: usize) -> AreaFactor {
        self.cache[i].prev_area
    }
}
