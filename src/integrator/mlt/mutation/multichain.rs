//! Veach's multi-chain perturbation (1997 sec. 11.4.4) for paths whose lens chain x_k S* x_m
//! is followed by more specular vertices, (L|D|V) S* D S* ... D S* E: the lens chain is perturbed
//! as in the sensor perturbation; then at each non-specular vertex x_c whose predecessor is
//! specular, the old direction x_c -> x_{c-1} is turned by theta, p(theta) ~ 1/theta on
//! [theta_min, theta_max], and the next chain is retraced in its old lobes, until a chain ends
//! at a vertex whose predecessor is non-specular (connect) or on the light itself.
//!
//! Transition density: the lens chain's (sensor perturbation) times, per further chain,
//! p(theta_c) / (2 pi sin theta_c) prod_i (g_i / d_i^2) over its retraced vertices.

use std::f32::consts::TAU;

use crate::math::Sampler;
use crate::path::geometry_term::to_area;
use crate::path::{LocalSampling, Vertex};
use crate::scene::Scene;

use super::super::contribution::{anchor_infinite, is_directional, is_specular, lobe_at};
use super::super::trace::{angle_between, chain_end_of, dir, perturb_direction, retrace_chain};
use super::light::direction_density;
use super::sensor::{lens_chain_density, lens_chain_end, perturb_lens_chain};
use super::{same_distance, same_prefix, InverseDistance, Mutation, Workspace};
use crate::bsdf::Lobe;

/// The multi-chain perturbation.
#[derive(Clone, Copy, Debug)]
pub struct MultiChainPerturbation {
    /// Film offset of the lens chain, in pixels.
    pub offset: InverseDistance,
    /// Turning angle at the later chains, in radians.
    pub angle: InverseDistance,
}

/// The chains after the lens chain: (c, e) with x_c the non-specular start (towards the light)
/// and x_e the end, e < c, every x_i with e < i < c specular. The last chain ends where the
/// predecessor of x_e is non-specular, or at the light (e = 0). Found as the iterator walks x.
fn later_chains<'a>(
    scene: &'a Scene,
    x: &'a [Vertex],
    m: usize,
) -> impl Iterator<Item = (usize, usize)> + Clone + 'a {
    let mut c = m;
    std::iter::from_fn(move || {
        if c < 1 || !is_specular(scene, &x[c - 1]) {
            return None;
        }
        let mut e = c - 1;
        while e >= 1 && is_specular(scene, &x[e]) {
            e -= 1;
        }
        let chain = (c, e);
        c = e;
        Some(chain)
    })
}

/// True when the last chain ends on a directional light, whose one direction a turned ray never
/// meets: such paths are left to the bidirectional mutation (a chain ending on the environment
/// escapes to a new direction, `ChainEnd::Environment`).
fn ends_at_directional(scene: &Scene, x: &[Vertex], m: usize) -> bool {
    later_chains(scene, x, m)
        .last()
        .is_some_and(|(_, e)| e == 0)
        && is_directional(scene, &x[0])
}

/// The lobes of a chain's specular vertices x_{c-1} ... x_{e+1} (tracing order).
fn chain_lobes<'a>(
    scene: &'a Scene,
    x: &'a [Vertex],
    c: usize,
    e: usize,
) -> impl Iterator<Item = Lobe> + 'a {
    (e + 1..c).rev().map(move |i| lobe_at(scene, x, i))
}

impl Mutation for MultiChainPerturbation {
    // ANCHOR: multichain_sample
    fn sample(
        &self,
        scene: &Scene,
        _tech: &dyn LocalSampling,
        x: &[Vertex],
        sampler: &mut Sampler,
        work: &mut Workspace,
        y: &mut Vec<Vertex>,
    ) -> Option<()> {
        let k = x.len() - 1;
        let m = lens_chain_end(scene, x)?;
        // no chain after the lens chain: the sensor perturbation's case
        later_chains(scene, x, m).next()?;
        if ends_at_directional(scene, x, m) {
            return None;
        }
        y.clear();
        y.extend_from_slice(x);
        let chain = &mut work.vertices;
        chain.clear();
        perturb_lens_chain(scene, x, m, &self.offset, sampler, chain)?;
        for (i, v) in (m..k).rev().zip(chain.iter()) {
            y[i] = *v;
        }
        for (c, e) in later_chains(scene, x, m) {
            let theta = self.angle.sample(sampler.next_f32());
            let phi = TAU * sampler.next_f32();
            let d = perturb_direction(dir(&x[c], &x[c - 1]), theta, phi);
            let end = chain_end_of(scene, &x[e], x[e + 1].p);
            chain.clear();
            retrace_chain(scene, &y[c], d, chain_lobes(scene, x, c, e), end, chain)?;
            for (i, v) in (e..c).rev().zip(chain.iter()) {
                y[i] = *v;
            }
        }
        // x_1 moved under a kept light at infinity, or a chain escaped to a new direction
        anchor_infinite(scene, y);
        Some(())
    }
    // ANCHOR_END: multichain_sample

    // ANCHOR: multichain_density
    fn transition_density(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        x: &[Vertex],
        y: &[Vertex],
        _work: &mut Workspace,
    ) -> f64 {
        let Some(m) = lens_chain_end(scene, x) else {
            return 0.0;
        };
        let chains = later_chains(scene, x, m);
        let Some((_, kept)) = chains.clone().last() else {
            return 0.0;
        };
        if y.len() != x.len() || !later_chains(scene, y, m).eq(chains.clone()) {
            return 0.0;
        }
        if ends_at_directional(scene, x, m) || ends_at_directional(scene, y, m) {
            return 0.0;
        }
        let mut t = lens_chain_density(scene, tech, x, y, m, &self.offset);
        if t == 0.0 || !same_prefix(x, y, kept) {
            return 0.0;
        }
        for (c, e) in chains {
            if !chain_lobes(scene, x, c, e).eq(chain_lobes(scene, y, c, e))
                || x[e].is_medium() != y[e].is_medium()
            {
                return 0.0;
            }
            if x[e].is_medium()
                && !same_distance(
                    (x[e].p - x[e + 1].p).length(),
                    (y[e].p - y[e + 1].p).length(),
                )
            {
                return 0.0;
            }
            let theta = angle_between(dir(&x[c], &x[c - 1]), dir(&y[c], &y[c - 1]));
            t *= direction_density(&self.angle, theta);
            for i in (e..c).rev() {
                t *= to_area(1.0, &y[i + 1], &y[i]) as f64;
            }
        }
        t
    }
    // ANCHOR_END: multichain_density
}
