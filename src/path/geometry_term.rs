//! The generalized geometry term (Pauly, Kollig, Keller 2000, sec. 3.2):
//! G(x <-> y) = V(x, y) g(x -> y) g(y -> x) / |x - y|^2, where g is |n(x) . w_xy| on a surface
//! and 1 in the medium (the "normal" of a medium vertex is w_xy itself). It converts a density
//! over solid angle at x into a density over area or volume at y, and the transmittance tau of
//! eq. (3) is kept as a separate factor, as in eq. (6), so it is never counted twice.

use super::Vertex;
use crate::math::Sampler;
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// g(v -> w): |n . w| on surfaces (and at area lights, meters, the camera), 1 in the medium and
/// at point-like lights.
#[inline]
pub fn cosine_factor(v: &Vertex, w: glam::Vec3) -> f32 {
    if v.n == glam::Vec3::ZERO {
        1.0
    } else {
        v.n.dot(w).abs()
    }
}

/// G(x <-> y) without visibility: g(x -> y) g(y -> x) / d^2. An infinite light's vertex at
/// either end contributes no distance and no cosine of its own (its area is measured
/// perpendicular to the direction).
// ANCHOR: geometry_term
pub fn geometry_term_unoccluded(x: &Vertex, y: &Vertex) -> f32 {
    // ASSIGNMENT: geometry_term
    let d = y.p - x.p;
    let d2 = d.length_squared();
    if d2 == 0.0 {
        return 0.0;
    }
    let w = d / d2.sqrt();
    if x.is_infinite_light() {
        return cosine_factor(y, w);
    }
    if y.is_infinite_light() {
        return cosine_factor(x, w);
    }
    cosine_factor(x, w) * cosine_factor(y, w) / d2
    // END ASSIGNMENT
}
// ANCHOR_END: geometry_term

/// G(x <-> y) V(x, y) and the transmittance tau(x <-> y): the two factors eq. (6) has per edge.
/// In inhomogeneous media tau is an estimate drawn from `sampler` (ratio tracking).
pub fn geometry_term(scene: &Scene, x: &Vertex, y: &Vertex, sampler: &mut Sampler) -> (f32, Rgb) {
    edge_factors(x, y, |a, b| scene.edge(a, b, sampler))
}

/// [`geometry_term`] with the exact tau (`Scene::edge_exact`): a deterministic function of
/// the two vertices, as MLT's target needs.
pub fn geometry_term_exact(scene: &Scene, x: &Vertex, y: &Vertex) -> (f32, Rgb) {
    edge_factors(x, y, |a, b| scene.edge_exact(a, b))
}

/// G V and tau of the edge x y, with `edge` evaluating its visibility and transmittance.
fn edge_factors(
    x: &Vertex,
    y: &Vertex,
    edge: impl FnOnce(crate::scene::EdgeEnd, crate::scene::EdgeEnd) -> crate::scene::EdgeEval,
) -> (f32, Rgb) {
    let g = geometry_term_unoccluded(x, y);
    if g == 0.0 {
        return (0.0, Rgb::ZERO);
    }
    let e = edge(x.edge_end(y.p), y.edge_end(x.p));
    if e.transmittance == Rgb::ZERO {
        return (0.0, Rgb::ZERO);
    }
    (g, e.transmittance)
}

/// Solid-angle density `pdf` at `from` converted to the measure of `to`.
#[inline]
pub fn to_area(pdf: f32, from: &Vertex, to: &Vertex) -> f32 {
    AreaFactor::new(from, to).apply(pdf)
}

/// The factor g(to -> from) / d^2 of [`to_area`] for one pair of vertices, kept in its two parts
/// so that a density converted with it rounds exactly as `to_area` rounds it (BDPT keeps one per
/// subpath edge for its weights).
#[derive(Clone, Copy, Debug, Default)]
pub struct AreaFactor {
    /// g(to -> from).
    cos: f32,
    /// The squared distance (0 for coincident vertices: no density).
    d2: f32,
    /// `to` is an infinite light's vertex: no distance and no cosine.
    infinite: bool,
}

impl AreaFactor {
    #[inline]
    pub fn new(from: &Vertex, to: &Vertex) -> Self {
        if to.is_infinite_light() {
            return AreaFactor {
                cos: 1.0,
                d2: 1.0,
                infinite: true,
            };
        }
        let d = to.p - from.p;
        let d2 = d.length_squared();
        let cos = if d2 == 0.0 {
            0.0
        } else {
            cosine_factor(to, d / d2.sqrt())
        };
        AreaFactor {
            cos,
            d2,
            infinite: false,
        }
    }

    /// The density `pdf` (per solid angle at `from`) in the measure of `to`.
    #[inline]
    pub fn apply(self, pdf: f32) -> f32 {
        if self.infinite {
            pdf
        } else if self.d2 == 0.0 {
            0.0
        } else {
            pdf * self.cos / self.d2
        }
    }
}
