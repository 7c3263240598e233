//! The bidirectional mutation (Veach 1997 sec. 11.4.1; Pauly, Kollig, Keller 2000 sec. 5.2,
//! Fig. 4): delete a contiguous section of x and regenerate it by local sampling from both ends
//! (Pauly et al. sec. 4: BSDF or phase function, then a free-flight distance by Table 1), then
//! join the two subpaths by one edge. Any path with a non-specular edge can be produced from
//! any other in one step, so the mutation is ergodic on its own.
//!
//! Indexing. x_0 ... x_k with x_k the camera vertex, which keeps its index: the pinhole is
//! never deleted (its position is fixed); a thin lens's point x_k is redrawn, uniform on the
//! aperture disk, whenever the deleted section reaches it (m = k below), so the eye side starts
//! from a new lens point as a camera subpath does.
//! A virtual vertex x_{-1} stands before the light so that the light vertex itself can be
//! deleted: the k + 1 edges (x_{-1}, x_0) ... (x_{k-1}, x_k) are candidates.
//! 1. Deleted edges k_d in 1 ..= k + 1 with Veach's p_d: weights 1/4, 1/2, then 2^-k_d,
//!    normalized; the first kept vertex x_l, l uniform in -1 ..= k - k_d; m = l + k_d.
//! 2. Added edges k_a with weight 2^-|k_a - k_d| (Veach: favour k_a = k_d), normalized over
//!    1 ..= (the length cap); at least 2 when l = -1 (a new light vertex is needed).
//! 3. s' of the k_a - 1 new vertices from the light side, uniform in 0 ..= k_a - 1;
//!    t' = k_a - 1 - s' from the eye side. With l = -1 and s' = 0 the eye side must hit an
//!    emitter by itself (BDPT's s = 0): the only way to reach paths such as L S D S E, which
//!    have no edge with two non-specular ends.
//!
//! Glowing media (eq. 5): a new light vertex is a volume vertex x0 with the media's share of
//! the emitted power, as BDPT's light subpaths start (`trace::sample_start_vertex`), and
//! leaves it uniformly over the sphere; with s' = 0 a collision of the eye side in a glowing
//! medium is the new x0. Their densities are `Vertex::light_origin_pdf` (per unit volume),
//! `Vertex::light_pdf_to` (1 / 4 pi times g / r^2) and the eye side's sigma_t tau g / r^2.
//!
//! Transition density (Veach eq. 11.6's form in the generalized path measure):
//! T(x -> y) = p_d(k_d) / (k - k_d + 2) * p_a(k_a | k_d, l) *
//!             sum_{s'} (1 / #splits) prod_{new light-side i} p_L(y_i) prod_{new eye-side i} p_E(y_i),
//! summed over the splits s' whose joining edge has two non-specular ends (the others cannot
//! produce a path with f > 0), times p_E(y_k) = 1 / (pi r^2) when a thin lens's point was
//! redrawn (m = k; a y that keeps x's lens point then has T = 0 unless x_{k-1} is kept too).
//! p_L, p_E are `contribution::singular_densities` of y. The kept vertices fix l and m: for
//! continuous vertices only one decomposition of y -> x agrees with both paths; a point light
//! at x_0 adds the one that resampled it onto itself.

use crate::bsdf::TransportMode;
use crate::math::Sampler;
use crate::path::{LocalSampling, Vertex, VertexKind};
use crate::scene::Scene;

/// The light-vertex kind of a surface vertex on an area light, or of the environment's vertex
/// an eye side escaped to (`None` elsewhere).
fn emitter_kind(scene: &Scene, v: &Vertex) -> Option<VertexKind> {
    if v.is_infinite_light() {
        return Some(v.kind);
    }
    let VertexKind::Surface { prim } = v.kind else {
        return None;
    };
    let light = scene.shapes[scene.prim_shape[prim as usize] as usize].light?;
    Some(VertexKind::Light {
        light,
        prim: Some(prim),
    })
}

use super::super::contribution::{
    anchor_infinite, is_delta_position_light, is_specular, same_vertex, singular_densities_into,
};
use super::super::trace::{
    extend, extend_from_infinite, extend_or_escape, is_volume_start, sample_direction,
    sample_start_vertex, sample_volume_direction,
};
use super::{Mutation, Workspace};

/// True when an eye side can end on light vertex `v` by itself: a point of an area light, the
/// environment's direction or a collision in a glowing medium (not a point, spot or
/// directional light: their Dirac is never met).
fn reachable_by_eye(scene: &Scene, v: &Vertex) -> bool {
    match v.kind {
        VertexKind::Light { prim, .. } => prim.is_some(),
        VertexKind::InfiniteLight { light, .. } => scene.environment == Some(light),
        VertexKind::Medium { .. } => is_volume_start(scene, v),
        _ => false,
    }
}

/// Draws a new lens point for camera vertex `v` of a thin lens, uniform on the aperture disk
/// (`Camera::sample_lens`, density `Camera::lens_pdf_area`); the pinhole's vertex stays and
/// draws no numbers, so its chains consume the stream as before.
fn resample_lens(scene: &Scene, v: &mut Vertex, sampler: &mut Sampler) -> Option<()> {
    let cam = scene.camera.as_ref()?;
    if v.kind == VertexKind::Camera && !cam.is_pinhole() {
        v.p = cam.sample_lens(sampler);
    }
    Some(())
}

/// True when both ends are camera vertices at different lens points: a proposal that redrew
/// x_k (the deleted section reached the camera, m = k).
fn new_lens_point(x_end: &Vertex, y_end: &Vertex) -> bool {
    x_end.kind == VertexKind::Camera && y_end.kind == VertexKind::Camera && x_end.p != y_end.p
}

/// Veach's weight of deleting k_d edges (sec. 11.4.1: "p_d[1] = 0.25, p_d[2] = 0.5, and
/// p_d[k] = 2^-k for k >= 3").
// ANCHOR: deletion_weight
pub fn deletion_weight(kd: usize) -> f64 {
    match kd {
        1 => 0.25,
        2 => 0.5,
        _ => 0.5f64.powi(kd as i32),
    }
}
// ANCHOR_END: deletion_weight

/// Weight of adding k_a edges after deleting k_d (favours equal lengths).
pub fn addition_weight(ka: usize, kd: usize) -> f64 {
    0.5f64.powi((ka as i64 - kd as i64).unsigned_abs().min(2000) as i32)
}

/// sum_{e = a}^{b} 2^-e (a <= b; b may be astronomically large: the tail is then below f64).
fn geometric_sum(a: usize, b: usize) -> f64 {
    let terms = (b - a).saturating_add(1).min(2000) as i32;
    2.0 * 0.5f64.powi(a.min(2000) as i32) * (1.0 - 0.5f64.powi(terms))
}

/// The bidirectional mutation.
#[derive(Clone, Debug)]
pub struct Bidirectional {
    /// Vertices a path may have (the length cap of the target, from `max_depth`);
    /// `usize::MAX` for the unbounded path space of an unlimited depth.
    pub max_vertices: usize,
}

impl Bidirectional {
    /// p_d(k_d) for a path of k edges.
    pub fn deletion_pmf(&self, kd: usize, k: usize) -> f64 {
        if kd == 0 || kd > k + 1 {
            return 0.0;
        }
        let total: f64 = (1..=k + 1).map(deletion_weight).sum();
        deletion_weight(kd) / total
    }

    /// The admissible k_a for l, k_d and a path of n vertices (the upper end unbounded, as
    /// `usize::MAX`, without a depth limit).
    pub fn addition_range(&self, l: i64, kd: usize, n: usize) -> (usize, usize) {
        let min = if l < 0 { 2 } else { 1 };
        let max = self.max_vertices.saturating_add(kd).saturating_sub(n);
        (min, max)
    }

    /// The sum of the addition weights over [lo, hi], in closed form (hi may be unbounded).
    fn addition_total(lo: usize, hi: usize, kd: usize) -> f64 {
        if hi < lo {
            return 0.0;
        }
        // below k_d the weights are 2^-(k_d - j), from k_d up 2^-(j - k_d)
        let below = if lo < kd {
            let top = hi.min(kd - 1);
            geometric_sum(kd - top, kd - lo)
        } else {
            0.0
        };
        let above = if hi >= kd {
            let bottom = lo.max(kd);
            geometric_sum(bottom - kd, hi - kd)
        } else {
            0.0
        };
        below + above
    }

    /// p_a(k_a | k_d, l) for a path of n vertices.
    pub fn addition_pmf(&self, ka: usize, kd: usize, l: i64, n: usize) -> f64 {
        let (lo, hi) = self.addition_range(l, kd, n);
        if ka < lo || ka > hi {
            return 0.0;
        }
        addition_weight(ka, kd) / Self::addition_total(lo, hi, kd)
    }

    /// k_a by inversion of p_a: the weights decay geometrically on both sides of k_d, so the
    /// walk up from `lo` ends within a few steps of k_d whatever the cap.
    pub fn sample_addition(u: f64, lo: usize, hi: usize, kd: usize) -> usize {
        /// Beyond this many steps past k_d the remaining mass is below 2^-64.
        const TAIL: usize = 64;
        let total = Self::addition_total(lo, hi, kd);
        let last = hi.min(kd.max(lo).saturating_add(TAIL));
        let mut acc = 0.0;
        for j in lo..=last {
            acc += addition_weight(j, kd) / total;
            if u < acc {
                return j;
            }
        }
        last
    }

    fn sample_discrete(u: f64, lo: usize, hi: usize, w: impl Fn(usize) -> f64) -> usize {
        let total: f64 = (lo..=hi).map(&w).sum();
        let mut acc = 0.0;
        for j in lo..=hi {
            acc += w(j) / total;
            if u < acc {
                return j;
            }
        }
        hi
    }
}

impl Mutation for Bidirectional {
    // ANCHOR: bidirectional_sample
    fn sample(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        x: &[Vertex],
        sampler: &mut Sampler,
        work: &mut Workspace,
        y: &mut Vec<Vertex>,
    ) -> Option<()> {
        let n = x.len();
        let k = n - 1;
        // 1. delete k_d edges after x_l
        let kd = Self::sample_discrete(sampler.next_f64(), 1, k + 1, deletion_weight);
        let l = sampler.next_index(k + 2 - kd) as i64 - 1;
        let m = (l + kd as i64) as usize;
        // 2. add k_a edges, 3. split the k_a - 1 new vertices
        let (lo, hi) = self.addition_range(l, kd, n);
        if hi < lo {
            return None;
        }
        let ka = Self::sample_addition(sampler.next_f64(), lo, hi, kd);
        let added = ka - 1;
        let s_new = sampler.next_index(added + 1);
        // the light side grows in y, the eye side in the workspace
        let light = y;
        light.clear();
        light.extend_from_slice(&x[..(l + 1) as usize]);
        for _ in 0..s_new {
            let v = match light.len() {
                // a light or, with the media's share of the power, a volume vertex x0
                0 => sample_start_vertex(scene, tech, sampler)?,
                // a light at infinity: a disk point, the ray along -w
                1 if light[0].is_infinite_light() => {
                    extend_from_infinite(scene, &light[0], sampler)?
                }
                // a volume x0 emits uniformly over the sphere
                1 if light[0].is_medium() => {
                    extend(scene, &light[0], sample_volume_direction(sampler), sampler)?
                }
                len => {
                    let prev = len.checked_sub(2).map(|i| &light[i]);
                    let cur = &light[len - 1];
                    let d = sample_direction(
                        scene,
                        tech,
                        prev,
                        cur,
                        TransportMode::Importance,
                        sampler,
                    )?;
                    extend(scene, cur, d, sampler)?
                }
            };
            light.push(v);
        }
        let eye = &mut work.vertices;
        eye.clear();
        eye.extend(x[m..].iter().rev());
        if m == k {
            // a thin lens's x_k goes with its edge: a new lens point (the pinhole draws none)
            resample_lens(scene, &mut eye[0], sampler)?;
        }
        for j in 0..added - s_new {
            let len = eye.len();
            let prev = len.checked_sub(2).map(|i| &eye[i]);
            let cur = &eye[len - 1];
            let d = sample_direction(scene, tech, prev, cur, TransportMode::Radiance, sampler)?;
            // the eye side's last vertex with no light side may escape to the environment
            let v = if light.is_empty() && j + 1 == added - s_new {
                extend_or_escape(scene, cur, d, sampler)?
            } else {
                extend(scene, cur, d, sampler)?
            };
            eye.push(v);
        }
        if light.is_empty() {
            // s' = 0 after deleting the light: the eye side must have found an emitter (a
            // collision in a glowing medium is one: the volume x0 of eq. 5)
            let last = eye.last_mut()?;
            if !is_volume_start(scene, last) {
                last.kind = emitter_kind(scene, last)?;
            }
        } else if is_specular(scene, &light[light.len() - 1])
            || is_specular(scene, &eye[eye.len() - 1])
        {
            // a joining edge at a Dirac lobe has f = 0 (a re-sampled specular chain can meet
            // its old direction within `SPECULAR_COS_TOLERANCE`: not a path T counts)
            return None;
        }
        light.extend(eye.iter().rev());
        anchor_infinite(scene, light);
        Some(())
    }
    // ANCHOR_END: bidirectional_sample

    // ANCHOR: bidirectional_density
    fn transition_density(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        x: &[Vertex],
        y: &[Vertex],
        work: &mut Workspace,
    ) -> f64 {
        let (nx, ny) = (x.len(), y.len());
        if nx < 2 || ny < 2 || ny > self.max_vertices {
            return 0.0;
        }
        let thin_lens = scene.camera.as_ref().is_some_and(|c| !c.is_pinhole());
        let new_lens = thin_lens && new_lens_point(&x[nx - 1], &y[ny - 1]);
        let common_suffix = if new_lens {
            1 // m = k: the lens point went with the deleted edge (x_k's index stays the end)
        } else {
            x.iter()
                .rev()
                .zip(y.iter().rev())
                .take_while(|(a, b)| same_vertex(a, b))
                .count()
        };
        // the pinhole is never deleted; a thin lens's point is redrawn whenever m = k, so y
        // keeps x's lens point with density zero unless x_{k-1} is kept too
        if common_suffix == 0 || (thin_lens && !new_lens && common_suffix == 1) {
            return 0.0;
        }
        let common_prefix = x
            .iter()
            .zip(y)
            .take_while(|(a, b)| same_vertex(a, b))
            .count()
            .min(nx - common_suffix)
            .min(ny - common_suffix);
        // a point light resampled onto itself: the light vertex was deleted too
        let resampled_light =
            (common_prefix == 1 && is_delta_position_light(scene, &x[0])).then_some(-1);
        let decompositions = std::iter::once(common_prefix as i64 - 1).chain(resampled_light);
        let k = nx - 1;
        let mut total = 0.0f64;
        for l in decompositions {
            let kd = (nx - common_suffix) as i64 - l;
            let ka = (ny - common_suffix) as i64 - l;
            if kd < 1 || ka < 1 {
                continue;
            }
            let (kd, ka) = (kd as usize, ka as usize);
            let p_delete = self.deletion_pmf(kd, k) / (k + 2 - kd) as f64;
            let p_add = self.addition_pmf(ka, kd, l, nx);
            if p_delete == 0.0 || p_add == 0.0 {
                continue;
            }
            let added = ka - 1;
            let splits = added + 1;
            let first = (l + 1) as usize; // index in y of the first new vertex
                                          // only the added vertices' densities enter (and only their edges are traced), and
                                          // a new lens point's area density 1 / (pi r^2) (`sensor_position_pdf`)
            let lens = usize::from(new_lens);
            let dy = &mut work.densities;
            singular_densities_into(scene, tech, y, first..first + added + lens, dy);
            let p_lens = if new_lens { dy.eye[ny - 1] as f64 } else { 1.0 };
            let mut sum = 0.0f64;
            for s_new in 0..=added {
                if l < 0 && s_new == 0 {
                    // no joining edge: the eye side reached the light by itself (an area
                    // light, the environment an eye side escaped to, or a collision in a
                    // glowing medium)
                    if !reachable_by_eye(scene, &y[0]) {
                        continue;
                    }
                } else {
                    // the joining edge (y_a, y_a+1)
                    let a = first + s_new - 1;
                    if is_specular(scene, &y[a]) || is_specular(scene, &y[a + 1]) {
                        continue;
                    }
                }
                let mut p = 1.0f64;
                for i in first..first + s_new {
                    p *= dy.light[i] as f64;
                }
                for i in first + s_new..first + added {
                    p *= dy.eye[i] as f64;
                }
                sum += p;
            }
            total += p_delete * p_add * p_lens * sum / splits as f64;
        }
        total
    }
    // ANCHOR_END: bidirectional_density
}
