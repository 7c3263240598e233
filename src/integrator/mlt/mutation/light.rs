//! The light perturbation (Pauly, Kollig, Keller 2000 sec. 5.2.1; Veach's caustic perturbation,
//! sec. 11.4.3): for a path ending in x_j S* x_{k-1} E with x_j and x_{k-1} non-specular, the
//! direction x_j -> x_{j+1} is turned by an angle theta, p(theta) ~ 1/theta on
//! [theta_min, theta_max], about a uniform azimuth; the ray is retraced through the specular
//! vertices in their old lobes to y_{k-1} (a surface, or a medium vertex at its old distance),
//! which is connected to the eye: the film position follows.
//!
//! Transition density: T(x -> y) = p(theta) / (2 pi sin theta) * prod_i (g_i / d_i^2) over the
//! retraced vertices y_{j+1} ... y_{k-1}. The direction density is symmetric; the Jacobian is
//! not.

use std::f32::consts::TAU;

use crate::math::Sampler;
use crate::path::geometry_term::to_area;
use crate::path::{LocalSampling, Vertex};
use crate::scene::Scene;

use super::super::contribution::{is_specular, lobe_at};
use super::super::trace::{angle_between, chain_end_of, dir, perturb_direction, retrace_chain};
use super::{same_distance, same_prefix, InverseDistance, Mutation, Workspace};
use crate::bsdf::Lobe;

/// The light perturbation.
#[derive(Clone, Copy, Debug)]
pub struct LightPerturbation {
    /// Angle in radians.
    pub angle: InverseDistance,
}

/// Index j of the non-specular vertex that starts the chain x_j S* x_{k-1}. `None` when x_j is
/// a light at infinity: its rays are parallel to w, a turn would change the light vertex
/// itself, so such paths are left to the bidirectional and sensor mutations.
pub fn caustic_chain_start(scene: &Scene, x: &[Vertex]) -> Option<usize> {
    let k = x.len().checked_sub(1)?;
    if k < 2 || is_specular(scene, &x[k - 1]) {
        return None;
    }
    let mut j = k - 2;
    while j >= 1 && is_specular(scene, &x[j]) {
        j -= 1;
    }
    (!x[j].is_infinite_light()).then_some(j)
}

/// The lobes of the chain's specular vertices x_{j+1} ... x_{k-2}.
fn lobes<'a>(scene: &'a Scene, x: &'a [Vertex], j: usize) -> impl Iterator<Item = Lobe> + 'a {
    let k = x.len() - 1;
    (j + 1..k - 1).map(move |i| lobe_at(scene, x, i))
}

/// p(theta) / (2 pi sin theta): the solid-angle density of the turned direction.
pub fn direction_density(angle: &InverseDistance, theta: f32) -> f64 {
    let s = theta.sin() as f64;
    if s <= 0.0 {
        return 0.0;
    }
    angle.pdf(theta) / (std::f64::consts::TAU * s)
}

impl Mutation for LightPerturbation {
    // ANCHOR: light_sample
    fn sample(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        x: &[Vertex],
        sampler: &mut Sampler,
        work: &mut Workspace,
        y: &mut Vec<Vertex>,
    ) -> Option<()> {
        let k = x.len() - 1;
        let j = caustic_chain_start(scene, x)?;
        let theta = self.angle.sample(sampler.next_f32());
        let phi = TAU * sampler.next_f32();
        let d = perturb_direction(dir(&x[j], &x[j + 1]), theta, phi);
        let end = chain_end_of(scene, &x[k - 1], x[k - 2].p);
        y.clear();
        y.extend_from_slice(&x[..=j]);
        retrace_chain(scene, &x[j], d, lobes(scene, x, j), end, y)?;
        y.push(x[k]);
        // the retraced end may land on a specular surface (a mirror strip next to the old
        // diffuse one), a specular vertex may change its lobe, or the angle measured between
        // the vertices may round out of [theta_min, theta_max]: y is then outside the
        // perturbation's support (T(x -> y) = 0), so it is no proposal at all
        if self.transition_density(scene, tech, x, y, work) <= 0.0 {
            return None;
        }
        Some(())
    }
    // ANCHOR_END: light_sample

    // ANCHOR: light_density
    fn transition_density(
        &self,
        scene: &Scene,
        _tech: &dyn LocalSampling,
        x: &[Vertex],
        y: &[Vertex],
        _work: &mut Workspace,
    ) -> f64 {
        let k = x.len() - 1;
        let Some(j) = caustic_chain_start(scene, x) else {
            return 0.0;
        };
        if y.len() != x.len() || caustic_chain_start(scene, y) != Some(j) {
            return 0.0;
        }
        if !same_prefix(x, y, j + 1)
            || y[k].p != x[k].p
            || !lobes(scene, x, j).eq(lobes(scene, y, j))
        {
            return 0.0;
        }
        if x[k - 1].is_medium() != y[k - 1].is_medium() {
            return 0.0;
        }
        if x[k - 1].is_medium()
            && !same_distance(
                (x[k - 1].p - x[k - 2].p).length(),
                (y[k - 1].p - y[k - 2].p).length(),
            )
        {
            return 0.0;
        }
        let theta = angle_between(dir(&x[j], &x[j + 1]), dir(&y[j], &y[j + 1]));
        let mut t = direction_density(&self.angle, theta);
        for i in j..k - 1 {
            t *= to_area(1.0, &y[i], &y[i + 1]) as f64;
        }
        t
    }
    // ANCHOR_END: light_density
}
