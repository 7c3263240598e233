//! The propagation perturbation (Pauly, Kollig, Keller 2000 sec. 5.2.2), the mutation designed
//! for media: if x_{k-1} is a medium vertex, it slides along the line x_{k-2} x_{k-1} by D,
//! p(D) ~ 1/D on [D_min, D_max], forwards or backwards with probability 1/2, and is connected
//! to the eye (one occlusion test). Rejected when y_{k-1} leaves the medium of x_{k-1} (or a
//! surface cuts the segment) or when x_{k-1} is on a surface.
//!
//! Transition density. The move keeps the direction w of x_{k-2} -> x_{k-1} and changes only
//! the distance t; in the coordinates (w, t) about x_{k-2} the volume measure is
//! dV = t^2 dw dt, so the density of y_{k-1} per unit of the measure the move explores is
//! T(x -> y) = (1/2) p(|t_y - t_x|) / t_y^2. The 1/2 p(D) part is symmetric; t^2 is not.
//!
//! A path x_0 x_1 whose x_0 is a volume vertex of a glowing medium (the pinhole sees the glow
//! directly, eq. 5) has no x_{k-2}: its x_0 slides along the line from the pinhole instead,
//! with the same density about the pinhole (t its distance from it), and stays on its pixel.

use crate::math::Sampler;
use crate::path::{LocalSampling, Vertex, VertexKind};
use crate::scene::Scene;

use super::super::contribution::{anchor_infinite, infinite_distance, SPECULAR_COS_TOLERANCE};
use super::super::trace::{dir, point_along};
use super::{same_prefix, InverseDistance, Mutation, Workspace};

/// Probability of moving towards x_{k-2} (and of moving away).
const DIRECTION_PROBABILITY: f64 = 0.5;

/// The propagation perturbation.
#[derive(Clone, Copy, Debug)]
pub struct PropagationPerturbation {
    /// Displacement in scene units.
    pub distance: InverseDistance,
}

impl Mutation for PropagationPerturbation {
    // ANCHOR: propagation_sample
    fn sample(
        &self,
        scene: &Scene,
        _tech: &dyn LocalSampling,
        x: &[Vertex],
        sampler: &mut Sampler,
        _work: &mut Workspace,
        y: &mut Vec<Vertex>,
    ) -> Option<()> {
        if x.len() == 2 {
            return self.sample_volume_start(scene, x, sampler, y);
        }
        // ASSIGNMENT: propagation_perturbation
        let k = x.len() - 1;
        if k < 2 || !x[k - 1].is_medium() {
            return None;
        }
        if x[k - 2].is_infinite_light() {
            return self.sample_parallel(scene, x, sampler, y);
        }
        let w = dir(&x[k - 2], &x[k - 1]);
        let t = (x[k - 1].p - x[k - 2].p).length();
        let d = self.distance.sample(sampler.next_f32());
        let t_new = if (sampler.next_f32() as f64) < DIRECTION_PROBABILITY {
            t + d
        } else {
            t - d
        };
        let v = point_along(scene, &x[k - 2], w, t_new)?;
        if v.kind != x[k - 1].kind {
            return None; // left the medium
        }
        y.clear();
        y.extend_from_slice(&x[..k - 1]);
        y.push(v);
        y.push(x[k]);
        Some(())
        // END ASSIGNMENT
    }
    // ANCHOR_END: propagation_sample

    // ANCHOR: propagation_density
    fn transition_density(
        &self,
        scene: &Scene,
        _tech: &dyn LocalSampling,
        x: &[Vertex],
        y: &[Vertex],
        _work: &mut Workspace,
    ) -> f64 {
        if x.len() == 2 {
            return self.volume_start_density(x, y);
        }
        // ASSIGNMENT: propagation_perturbation
        let _ = scene;
        let k = x.len() - 1;
        if k < 2 || y.len() != x.len() || !x[k - 1].is_medium() || y[k - 1].kind != x[k - 1].kind {
            return 0.0;
        }
        if !same_prefix(x, y, k - 1) || y[k].p != x[k].p {
            return 0.0;
        }
        if x[k - 2].is_infinite_light() {
            return self.parallel_density(scene, x, y);
        }
        if dir(&x[k - 2], &x[k - 1]).dot(dir(&y[k - 2], &y[k - 1])) < 1.0 - SPECULAR_COS_TOLERANCE {
            return 0.0;
        }
        let tx = (x[k - 1].p - x[k - 2].p).length();
        let ty = (y[k - 1].p - y[k - 2].p).length();
        DIRECTION_PROBABILITY * self.distance.pdf((ty - tx).abs()) / (ty as f64 * ty as f64)
        // END ASSIGNMENT
    }
    // ANCHOR_END: propagation_density
}

/// The slide of x_1 along the ray of a light at infinity x_0 (k = 2): the line is parallel to w,
/// the volume measure in the coordinates (position across the ray, distance along it) is
/// dA_perp dt, so T(x -> y) = (1/2) p(|t_y - t_x|) with no t^2 (book: "Metropolis light
/// transport", lights at infinity).
impl PropagationPerturbation {
    fn sample_parallel(
        &self,
        scene: &Scene,
        x: &[Vertex],
        sampler: &mut Sampler,
        y: &mut Vec<Vertex>,
    ) -> Option<()> {
        let VertexKind::InfiniteLight { w, .. } = x[0].kind else {
            return None;
        };
        let d = self.distance.sample(sampler.next_f32());
        let sign = if (sampler.next_f32() as f64) < DIRECTION_PROBABILITY {
            1.0
        } else {
            -1.0
        };
        // from a far point on x_1's line, so that point_along sees every surface before it
        let far = infinite_distance(scene, x[1].p);
        let mut origin = x[0];
        origin.p = x[1].p + w * far;
        let v = point_along(scene, &origin, -w, far + sign * d)?;
        if v.kind != x[1].kind {
            return None; // left the medium
        }
        y.clear();
        y.extend_from_slice(x);
        y[1] = v;
        anchor_infinite(scene, y);
        Some(())
    }

    /// (1/2) p(D) for y_1 on x_1's line along w, D = |y_1 - x_1|; zero off the line.
    fn parallel_density(&self, scene: &Scene, x: &[Vertex], y: &[Vertex]) -> f64 {
        let VertexKind::InfiniteLight { w, .. } = x[0].kind else {
            return 0.0;
        };
        let step = y[1].p - x[1].p;
        let off_line = step.cross(w).length();
        if off_line > PARALLEL_TOLERANCE * scene.radius.max(f32::MIN_POSITIVE) {
            return 0.0;
        }
        DIRECTION_PROBABILITY * self.distance.pdf(step.length())
    }
}

/// Distance of y_1 from x_1's line along w (relative to the scene's radius) that still counts as
/// on it: the slide starts from a point 4R to 6R away, whose rounding moves y_1 by ~1e-6 R.
const PARALLEL_TOLERANCE: f32 = 1e-4;

impl PropagationPerturbation {
    /// The glow seen directly, x_0 (a volume vertex) x_1 (the pinhole): x_0 moved by D along
    /// the pinhole's ray, forwards or backwards; `None` for a light's x_0 or when y_0 leaves
    /// x_0's medium.
    fn sample_volume_start(
        &self,
        scene: &Scene,
        x: &[Vertex],
        sampler: &mut Sampler,
        y: &mut Vec<Vertex>,
    ) -> Option<()> {
        if !x[0].is_medium() {
            return None;
        }
        let w = dir(&x[1], &x[0]);
        let t = (x[0].p - x[1].p).length();
        let d = self.distance.sample(sampler.next_f32());
        let t_new = if (sampler.next_f32() as f64) < DIRECTION_PROBABILITY {
            t + d
        } else {
            t - d
        };
        let v = point_along(scene, &x[1], w, t_new)?;
        if v.kind != x[0].kind {
            return None;
        }
        y.clear();
        y.push(v);
        y.push(x[1]);
        Some(())
    }

    /// T(x -> y) of [`Self::sample_volume_start`]: (1/2) p(|t_y - t_x|) / t_y^2 per unit
    /// volume of y_0, t the distance from the pinhole.
    fn volume_start_density(&self, x: &[Vertex], y: &[Vertex]) -> f64 {
        if y.len() != 2 || !x[0].is_medium() || y[0].kind != x[0].kind || y[1].p != x[1].p {
            return 0.0;
        }
        if dir(&x[1], &x[0]).dot(dir(&y[1], &y[0])) < 1.0 - SPECULAR_COS_TOLERANCE {
            return 0.0;
        }
        let tx = (x[0].p - x[1].p).length();
        let ty = (y[0].p - y[1].p).length();
        DIRECTION_PROBABILITY * self.distance.pdf((ty - tx).abs()) / (ty as f64 * ty as f64)
    }
}
