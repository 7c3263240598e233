//! The ray-marching estimator with the joint virtual domain (Pegoraro, Wald, Parker 2008,
//! eq. 8 and 9).
//!
//! eq. (8): over an interval dx where the medium is constant,
//!   L(x + dx) = kappa_t L(x) + kappa_s L_i,  kappa_t = e^(-sigma_t dx),
//!   kappa_s = (1 - e^(-sigma_t dx)) sigma_s / sigma_t.
//! eq. (9): both terms are one integral I over the virtual domain Omega_t U Omega_s, Omega_t a
//! single point of measure 1 (the transmission direction) and Omega_s the sphere (measure
//! 4 pi), so one sample decides between continuing the ray and scattering, and one ray
//! estimates both the transmitted and the in-scattered radiance.
//!
//! Predicates on the joint domain [PWP08 sec. 4.5]: G = kappa_s G_s + kappa_t L~(d) where G_s
//! is the cache's spherical integral and L~(d) its reconstruction in the transmission
//! direction d. On Omega_t, p = P_t and f = kappa_t L (a newly traced continuation); on
//! Omega_s, p = (1 - P_t) p(w) and f = kappa_s f_p L(w), with p(w) the cache's pdf mixed with
//! the phase function (is1 at the first [`super::ADAPTIVE_DEPTH`] vertices, [`super::DEFENSIVE`])
//! or the phase function.
//!
//! DEVIATION: eq. (8) evaluates L_i at the start of the interval, an O(dx) bias. Here the
//! scattering point is jittered in the interval by the free-flight density truncated to it,
//! q(s) = sigma(s) e^(-tau(s)) / (1 - e^(-tau(dx))) (channel means), and the in-scattered term
//! is weighted by sigma_s(s) e^(-tau(s)) / q(s), whose expectation is exactly
//! int_0^dx sigma_s e^(-tau(s)) L_i(x + s) ds: the march is unbiased, while g, G and the
//! sampling probabilities keep the paper's kappa_s.
//!
//! DEVIATION: the paper completes its probability tree on the fly with the masses
//! kappa_t c(d) and kappa_s mean(c) (c the pdf coefficients), so that
//! P_t = kappa_t c(d) / (kappa_t c(d) + kappa_s mean(c)). That choice is made at every step,
//! and a ray that passes n steps carries the product of n ratios (analog / adaptive) of which
//! a single small c(d) makes each large: even kept within a factor 4 of the analog probability
//! the image of the heterogeneous cloud came out 3% (step 1 mfp) to 8% (step 1/4 mfp) dark,
//! a heavy tail that the analog choice P_t = kappa_t / (kappa_t + kappa_s) does not have. The
//! control variate still covers the joint domain (G includes kappa_t L~(d)), which is where
//! the method's gain on the test bed comes from (book: "SMC: experiments").
//!
//! DEVIATION: steps have equal optical depth (`step` mean free paths), not equal length: the
//! same thing in a homogeneous medium, and in an inhomogeneous one the only way to keep the
//! number of decisions per mean free path bounded; each step's kappas use its exact optical
//! depth, so the medium is read along the whole step, not where the ray entered it.
//! Book: "SMC: the estimators", section "Ray marching on Omega_t U Omega_s (eq. 8, 9)".

use super::walk::{self, Link, Previous, Scratch};
use super::Smc;
use crate::geometry::Ray;
use crate::math::{warp, Sampler};
use crate::scene::Scene;
use crate::spectrum::{self, Rgb};

/// Relative step past a crossed null boundary, the same rule as `Scene::propagate` (the ray
/// is continued, never re-spawned).
const NULL_CROSSING_EPSILON: f32 = 1e-6;
/// More null crossings than this along one ray means the geometry traps the ray.
const MAX_NULL_CROSSINGS: usize = 256;
/// Marching steps along one ray after which the ray is abandoned (its remaining transmittance
/// is below e^-MAX_MARCH_STEPS * step in a medium of any thickness that reaches this count).
const MAX_MARCH_STEPS: usize = 1 << 20;

#[inline]
fn past(t: f32, ray: &Ray) -> f32 {
    t + NULL_CROSSING_EPSILON * (1.0 + t + ray.o.abs().max_element())
}

/// The probability of Omega_t for masses `m_t` (transmission) and `m_s` (scattering).
#[inline]
fn transmit_probability(m_t: f64, m_s: f64) -> f64 {
    if m_s > 0.0 {
        m_t / (m_t + m_s)
    } else {
        1.0
    }
}

/// A point s in [0, dx) of the step `here` of mean optical depth `tau`, drawn by the free-flight
/// density truncated to the step, q(s) = sigma(s) e^(-tau(s)) / (1 - e^(-tau)) with the
/// channel means (inverted in optical depth, exactly), and the weight
/// sigma_s(s) e^(-tau(s)) / q(s) per channel that makes the in-scattered term unbiased for the
/// integral of sigma_s e^-tau L_i over the step.
#[inline]
fn jittered_point(
    med: &crate::medium::Medium,
    here: &Ray,
    dx: f32,
    tau: f32,
    sampler: &mut Sampler,
) -> (f32, Rgb) {
    let u = sampler.next_f32();
    if tau.is_nan() || tau <= 0.0 {
        // no extinction in the step: nothing scatters (kappa_s is zero too)
        return (u * dx, Rgb::ZERO);
    }
    let one_minus = -(-tau).exp_m1();
    let tau_s = -(1.0 - u * one_minus).ln();
    let s = med.advance(here, tau_s, dx).unwrap_or(dx).clamp(0.0, dx);
    let p = here.at(s);
    let tau_s = med.optical_depth(here, s);
    let q = spectrum::average(med.sigma_t(p)) * (-spectrum::average(tau_s)).exp() / one_minus;
    if q.is_nan() || q <= 0.0 {
        return (s, Rgb::ZERO);
    }
    (s, med.sigma_s(p) * (-tau_s).exp() / q)
}

/// The marching walk from `ray` (in `medium`) with throughput `beta`; `step_mfp` is the step
/// in mean free paths.
// ANCHOR: march
#[allow(clippy::too_many_arguments)]
pub fn walk(
    smc: &Smc,
    scene: &Scene,
    mut ray: Ray,
    mut medium: Option<u32>,
    mut prev: Previous,
    mut beta: Rgb,
    step_mfp: f32,
    sampler: &mut Sampler,
    scratch: &mut Scratch,
) {
    let variant = smc.settings.variant;
    let cv = variant.cv;
    let mut depth = 0;
    'rays: loop {
        let (mut t_start, mut t_min) = (0.0f32, 0.0f32);
        let mut crossings = 0;
        loop {
            crossings += 1;
            if crossings > MAX_NULL_CROSSINGS {
                return;
            }
            let hit = scene.bvh.intersect_range(
                &scene.prims,
                &scene.prim_opaque,
                &ray,
                t_min,
                f32::INFINITY,
            );
            let t_hit = hit.map_or(f32::INFINITY, |h| h.t);
            if let Some(m) = medium {
                let med = &scene.media[m as usize];
                // steps of `step_mfp` mean free paths: equal optical depth, so that an
                // inhomogeneous medium gets as many decisions per mean free path as a
                // homogeneous one (see DEVIATION above)
                if spectrum::average(med.sigma_t_max()) > 0.0 {
                    let albedo = med.albedo();
                    let d = ray.d;
                    let mut t = t_start;
                    let mut steps = 0;
                    while t < t_hit {
                        steps += 1;
                        if steps > MAX_MARCH_STEPS {
                            return;
                        }
                        let here = Ray::new(ray.at(t), d);
                        let dx = med.advance(&here, step_mfp, t_hit - t).unwrap_or(t_hit - t);
                        // the step's exact optical depth (eq. 8's kappas for the medium as it is
                        // along the step)
                        let tau = med.optical_depth(&here, dx);
                        let kappa_t = (-tau).exp();
                        let kappa_s = if depth < smc.max_depth {
                            (Rgb::ONE - kappa_t) * albedo
                        } else {
                            Rgb::ZERO
                        };
                        // the scattering point, jittered in the step (see DEVIATION above);
                        // drawn before the branch so that both branches share G
                        let (s, kappa_s_jit) =
                            jittered_point(med, &here, dx, spectrum::average(tau), sampler);
                        let xs = ray.at(t + s);
                        let x_end = ray.at(t + dx);
                        // the snapshot's caches: where the transmitted radiance L(x + dx, d)
                        // arrives, and where the in-scattered radiance is estimated
                        let cache_t = smc.octree.cache(x_end);
                        let cache_s = smc.octree.cache(xs);
                        // the vertex this step would scatter at: the (depth + 1)-th
                        let use_cache = smc.adaptive(cache_s, depth + 1);
                        // the choice between Omega_t and Omega_s by the analog masses
                        // kappa_t and kappa_s (see DEVIATION above)
                        let p_t = transmit_probability(
                            spectrum::average(kappa_t) as f64,
                            spectrum::average(kappa_s) as f64,
                        ) as f32;
                        // g on Omega_t and G on the joint domain
                        let g_t = kappa_t * cache_t.radiance(d, cv);
                        let big_g = kappa_s * cache_s.integral(cv) + g_t;
                        if sampler.next_f32() < p_t {
                            // Omega_t: the transmitted radiance, by continuing the ray
                            let b = kappa_t / p_t;
                            scratch.links.push(Link {
                                a: big_g - g_t / p_t,
                                b,
                                record: Some((x_end, d, warp::INV_FOUR_PI)),
                                roulette: None,
                            });
                            beta *= b;
                            t += dx;
                            continue;
                        }
                        // Omega_s: the in-scattered radiance at the jittered point; p is the
                        // joint density of (Omega_s, wi)
                        let p_s = 1.0 - p_t;
                        let phase = med.phase();
                        let wo = -d;
                        let (wi, p) = if use_cache {
                            let (wi, p_dir) =
                                super::defensive_direction(cache_s, phase, wo, sampler);
                            (wi, p_s * p_dir)
                        } else {
                            let ps = phase.sample(wo, sampler.next_2d());
                            (ps.wi, p_s * ps.pdf)
                        };
                        if p.is_nan() || p <= 0.0 {
                            return;
                        }
                        let phase_value = phase.eval(wo, wi);
                        let g = kappa_s * cache_s.g(wi, cv);
                        let delta =
                            walk::delta_lights(scene, xs, Some(m), sampler, |w| phase.eval(wo, w));
                        let b = kappa_s_jit * (phase_value / p);
                        let mut link = Link {
                            a: big_g - g / p + kappa_s_jit * delta / p_s,
                            b,
                            record: Some((xs, wi, phase_value)),
                            roulette: None,
                        };
                        depth += 1;
                        beta *= b;
                        let c = cache_s.radiance(wi, cv);
                        let alive = walk::roulette(depth, &mut beta, c, &mut link, sampler);
                        scratch.links.push(link);
                        if !alive {
                            return;
                        }
                        ray = Ray::new(xs, wi);
                        prev = Previous::singular(xs);
                        continue 'rays;
                    }
                }
            }
            // the end of the segment: background, null boundary or surface
            let Some(hit) = hit else {
                let a = walk::escaped(scene, ray.d, &prev);
                scratch.links.push(Link::plain(a, Rgb::ZERO));
                return;
            };
            let shape = scene.shape_of(&hit);
            if shape.is_null() {
                medium = shape.medium_after(ray.d, hit.ng, medium);
                t_start = hit.t;
                t_min = past(hit.t, &ray);
                continue;
            }
            let st = walk::surface(
                scene,
                &ray,
                &hit,
                medium,
                &prev,
                &mut depth,
                smc.max_depth,
                sampler,
            );
            let Some((w, next_ray, next_medium, next_prev)) = st.next else {
                scratch.links.push(Link::plain(st.a, Rgb::ZERO));
                return;
            };
            let mut link = Link::plain(st.a, w);
            beta *= w;
            let alive = walk::roulette(depth, &mut beta, Rgb::ZERO, &mut link, sampler);
            scratch.links.push(link);
            if !alive {
                return;
            }
            ray = next_ray;
            medium = next_medium;
            prev = next_prev;
            continue 'rays;
        }
    }
}
// ANCHOR_END: march
