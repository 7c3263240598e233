//! Densities of a path under local sampling from either end (Pauly, Kollig, Keller 2000,
//! sec. 4): for every vertex x_i, the density p_L(x_i) with which a light subpath reaches it
//! from x_{i-1} (and x_{i-2}), and the density p_E(x_i) with which an eye subpath reaches it
//! from x_{i+1} (and x_{i+2}), in the vertex's own measure (area on surfaces, volume in the
//! medium): the scattering pdf over solid angle converted by g / d^2, times the propagation pdf
//! of Table 1 (sigma_t tau for a medium vertex, tau for a surface reached through the medium).
//!
//! The density of the path sampled by strategy (s, t) is prod_{i<s} p_L(x_i) prod_{i>=s} p_E(x_i);
//! the sampler's cached densities must equal these (see `verify`).

use super::{LocalSampling, Path, Vertex, VertexKind};
use crate::bsdf::TransportMode::{Importance, Radiance};
use crate::math::Sampler;
use crate::scene::Scene;

/// p_L(x_i) and p_E(x_i) for every vertex of a path x_0 (light) ... x_k (sensor).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Densities {
    pub light: Vec<f32>,
    pub eye: Vec<f32>,
    /// Propagation pdf of edge (x_i, x_{i+1}) walked from x_i to x_{i+1}.
    pub prop_up: Vec<f32>,
    /// The same edge walked from x_{i+1} to x_i.
    pub prop_down: Vec<f32>,
}

impl Densities {
    /// Zeros for a path of `n` vertices, in the buffers already allocated.
    fn reset(&mut self, n: usize) {
        let zero = |b: &mut Vec<f32>, len: usize| {
            b.clear();
            b.resize(len, 0.0);
        };
        zero(&mut self.light, n);
        zero(&mut self.eye, n);
        zero(&mut self.prop_up, n.saturating_sub(1));
        zero(&mut self.prop_down, n.saturating_sub(1));
    }
}

/// The densities of every vertex from both ends (the light vertex's own density is its
/// light-origin density; the sensor vertex's is the sensor's position density).
// ANCHOR: densities
pub fn densities(
    scene: &Scene,
    tech: &dyn LocalSampling,
    path: &Path,
    sampler: &mut Sampler,
) -> Densities {
    let n = path.vertices.len();
    densities_in(scene, tech, &path.vertices, 0..n, sampler)
}

/// `densities` for the vertices `range` only (the others stay 0), tracing only the edges they
/// need: p_L(x_i) needs edge (x_{i-1}, x_i), p_E(x_i) edge (x_i, x_{i+1}). A bidirectional
/// mutation's transition density needs just the vertices it added.
pub fn densities_in(
    scene: &Scene,
    tech: &dyn LocalSampling,
    v: &[Vertex],
    range: std::ops::Range<usize>,
    sampler: &mut Sampler,
) -> Densities {
    let mut d = Densities::default();
    densities_into(scene, tech, v, range, sampler, &mut d);
    d
}

/// `densities_in` written into `d`, whose buffers are reused (MLT computes a transition
/// density per mutation, and a chain keeps one `Densities` for all of them).
pub fn densities_into(
    scene: &Scene,
    tech: &dyn LocalSampling,
    v: &[Vertex],
    range: std::ops::Range<usize>,
    sampler: &mut Sampler,
    d: &mut Densities,
) {
    let n = v.len();
    d.reset(n);
    let range = range.start.min(n)..range.end.min(n);
    if n < 2 || range.is_empty() {
        return;
    }
    for i in range.start.saturating_sub(1)..range.end.min(n - 1) {
        let e = scene.edge(
            v[i].edge_end(v[i + 1].p),
            v[i + 1].edge_end(v[i].p),
            sampler,
        );
        d.prop_up[i] = e.pdf_ab;
        d.prop_down[i] = e.pdf_ba;
    }
    // a scattering vertex that took a Dirac lobe (plastic's coat; a mirror's and glass's
    // `pdf` is zero anyway) has no density, as the walks cache it (`Bdpt::scatter`)
    let dirac = |j: usize| j > 0 && j + 1 < n && v[j].delta;
    // from the light
    for i in range.clone() {
        d.light[i] = if i == 0 {
            v[0].light_origin_pdf(scene, tech)
        } else if dirac(i - 1) {
            0.0
        } else {
            let prev = if i >= 2 { Some(v[i - 2].p) } else { None };
            v[i - 1].pdf_area(scene, tech, prev, &v[i], Importance) * d.prop_up[i - 1]
        };
    }
    // from the sensor
    for i in range.rev() {
        d.eye[i] = if i == n - 1 {
            sensor_position_pdf(scene, &v[n - 1])
        } else if dirac(i + 1) {
            0.0
        } else {
            let prev = if i + 2 < n { Some(v[i + 2].p) } else { None };
            v[i + 1].pdf_area(scene, tech, prev, &v[i], Radiance) * d.prop_down[i]
        };
    }
}
// ANCHOR_END: densities

/// Density of the sensor vertex's position: 1 for the pinhole (a Dirac), 1/A on a thin lens
/// or a meter.
pub fn sensor_position_pdf(scene: &Scene, v: &Vertex) -> f32 {
    match v.kind {
        VertexKind::Camera => scene.camera.as_ref().map_or(1.0, |c| c.lens_pdf_area()),
        VertexKind::Meter { meter } => {
            1.0 / crate::geometry::Primitive::Quad(scene.sensors[meter as usize].quad).area()
        }
        _ => 0.0,
    }
}

/// The density of the path as sampled by strategy (s, t = k + 1 - s).
pub fn strategy_pdf(d: &Densities, s: usize) -> f64 {
    let light: f64 = d.light[..s].iter().map(|&p| p as f64).product();
    let eye: f64 = d.eye[s..].iter().map(|&p| p as f64).product();
    light * eye
}
