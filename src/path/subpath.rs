//! What BDPT's connections read from the vertices of a subpath besides the vertices themselves:
//! a vertex's density ratio for the MIS weight, the unit direction to its predecessor and the
//! factor converting a density at it into its predecessor's measure. Every connection through
//! a vertex needs the same three values, so `Bdpt::combine` computes them once per sample
//! ([`Cached`]), while the other callers compute them on the fly (`[Vertex]`): both with the
//! functions below, so a weight rounds the same either way.
//! Book: "Measuring a renderer", "Where the time goes".

use glam::Vec3;

use super::geometry_term::{geometry_term_unoccluded, AreaFactor};
use super::Vertex;

/// A density in the MIS ratios: zero (an unset density) counts as one. The zeros a Dirac
/// vertex leaves on its neighbours are replaced first ([`fwd_density`], [`rev_density`]).
#[inline]
pub fn remap(f: f32) -> f32 {
    if f != 0.0 {
        f
    } else {
        1.0
    }
}

/// The ratio p_rev / p_fwd of vertex `i` of `path`, the factor it adds to the weights of the
/// strategies beyond it (Veach 1997, eq. 10.9), with both densities in the measures of
/// [`fwd_density`] and [`rev_density`].
#[inline]
pub fn ratio(path: &[Vertex], i: usize) -> f32 {
    let v = &path[i];
    let fwd = match i.checked_sub(1) {
        Some(a) => fwd_density(&path[a], v, v.delta),
        None => v.pdf_fwd,
    };
    let rev = match path.get(i + 1) {
        Some(b) => rev_density(v, b, v.pdf_rev, v.delta),
        None => v.pdf_rev,
    };
    remap(rev) / remap(fwd)
}

/// The density of vertex `v` sampled from its subpath predecessor `a`, in the measure the MIS
/// ratios compare (`dirac`: `v` took a Dirac lobe in the path being weighted). Away from Dirac
/// vertices it is `v.pdf_fwd`. After a Dirac predecessor the direction is a point mass, and
/// `v`'s density is the edge's propagation pdf alone (`prop_fwd`; the lobe's choice is the
/// same both ways and cancels). A Dirac vertex sampled from a non-Dirac one keeps its density
/// per projected solid angle at that one ([`projected`]): the densities of two strategies that
/// differ by a chain of Dirac vertices then differ by the projected densities at the chain's
/// two ends, with the propagation pdfs of both directions (Veach 1997, sec. 10.3.5).
#[inline]
pub fn fwd_density(a: &Vertex, v: &Vertex, dirac: bool) -> f32 {
    if a.delta {
        v.prop_fwd
    } else if dirac {
        projected(v.pdf_fwd, v, a)
    } else {
        v.pdf_fwd
    }
}

/// [`fwd_density`] the other way: the density `pdf_rev` of vertex `v` sampled from its
/// subpath successor `b` (the reverse walk), in the measure the MIS ratios compare.
#[inline]
pub fn rev_density(v: &Vertex, b: &Vertex, pdf_rev: f32, dirac: bool) -> f32 {
    if b.delta {
        b.prop_rev
    } else if dirac {
        projected(pdf_rev, v, b)
    } else {
        pdf_rev
    }
}

/// A density per unit area (volume) at Dirac vertex `dirac` sampled from the non-Dirac vertex
/// `from`, turned into the density per projected solid angle at `from`: divided by
/// G(from <-> dirac). The Jacobian through a chain of Dirac vertices is the same seen from
/// either end (book: "Bidirectional path tracing", G_chain), so it cancels from the ratio of
/// two strategies' densities only when both chain ends are measured this way; a Dirac density
/// counted as 1 in the area measure leaves d^2 and the cosines in the ratio.
#[inline]
pub fn projected(pdf_area: f32, dirac: &Vertex, from: &Vertex) -> f32 {
    let g = geometry_term_unoccluded(dirac, from);
    if g > 0.0 && g.is_finite() {
        pdf_area / g
    } else {
        pdf_area
    }
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
                ratio: ratio(path, i),
                ..VertexCache::default()
            }
        } else {
            VertexCache {
                ratio: ratio(path, i),
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
        ratio(self, i)
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
