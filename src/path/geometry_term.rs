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
