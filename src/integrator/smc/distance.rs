//! The unbiased distance-sampling estimator (Pegoraro, Wald, Parker 2008, eq. 7 and the
//! pseudo-code of Fig. 2).
//!
//! eq. (7): L(x, w) = int_x^x_inf e^-tau sigma_t [x' - x < x_0 - x ? L_t(x') : L_b(x_0)] dx'
//! with the source L_t = (sigma_a L_e + sigma_s L_i) / sigma_t: a free-flight distance sampled
//! with density sigma_t e^-tau either lands in the medium, where L_i is estimated by the
//! combined estimator of eq. (1) with the cache of the leaf containing the point, or passes,
//! and the background (or the next surface) is seen.
//!
//! Fig. 2, line by line (anchor `fig2` below):
//!  2 `GetSamplePositionFromRayPDF` -> `scene.propagate` (Table 1 free flight, through null
//!    boundaries); `weight` is its transmittance times sigma_s over its pdf (the albedo);
//!  3 `position < mediumBoundary` -> `Event::Medium`;
//!  4 `octree.GetCache(position)` -> `smc.octree.cache(p)`, a snapshot of the structure;
//!  5-8 `GetSampleDirection`, `GetIntegralForIsotropicPhaseFunction`, `GetRadiance` times the
//!    isotropic phase function -> `smc.in_scatter` (wi, p, G, g);
//!  9-10 `TraceRay` times the phase function -> the rest of the chain: f = f_p R_{k+1};
//!  11 `estimate = G + (f - g) / p` -> the link a = G - g / p, b = f_p / p;
//!  12-14 `AddRecordToCache`, `Refine` -> the link's record, merged after the pass
//!    ([`super::Smc::merge`]) so that every estimate of the pass sees the same snapshot;
//!  15-16 `TraceBackgroundRay` -> `Event::Escape` (or a surface vertex);
//!  17 `estimate * weight` -> every link is multiplied by `weight`.
//!
//! Book: "SMC: the estimators", section "Distance sampling (eq. 7, Fig. 2)".

use super::walk::{self, Link, Previous, Scratch, State};
use super::Smc;
use crate::geometry::Ray;
use crate::math::Sampler;
use crate::scene::{Event, Scene};
use crate::spectrum::Rgb;

/// The walk of `s` (its ray, medium, throughput), appending links to `scratch`.
// ANCHOR: fig2
pub fn walk(smc: &Smc, scene: &Scene, mut s: State, sampler: &mut Sampler, scratch: &mut Scratch) {
    loop {
        // line 2: a distance by the free-flight pdf of the ray (eq. 7)
        // medium segments are measured from the vertex itself, not the lifted origin
        let lead = (s.ray.o - s.prev.p).dot(s.ray.d).max(0.0);
        // the camera's rays see through hidden emitters until the first scattering vertex
        let prop = scene.propagate_from(s.ray, lead, s.medium, s.depth == 0, sampler);
        let weight = prop.weight();
        // eq. (7)'s source term sigma_a L_e / sigma_t: the emission of the medium at a collision
        let emitted = walk::emitted(scene, &prop);
        if weight == Rgb::ZERO {
            if emitted != Rgb::ZERO {
                scratch.links.push(Link::plain(emitted, Rgb::ZERO));
            }
            return;
        }
        match prop.event {
            // lines 3-14: a medium vertex
            Event::Medium { p, medium: m, .. } => {
                if s.depth >= smc.max_depth {
                    if emitted != Rgb::ZERO {
                        scratch.links.push(Link::plain(emitted, Rgb::ZERO));
                    }
                    return;
                }
                s.depth += 1;
                let phase = scene.media[m as usize].phase();
                let wo = -s.ray.d;
                // line 4: the snapshot's cache at the position
                let cache = smc.octree.cache(p);
                // lines 5-8: (direction, p), G, g
                let is = smc.in_scatter(cache, phase, wo, s.depth, sampler);
                let delta = walk::delta_lights(scene, p, Some(m), sampler, |wi| phase.eval(wo, wi));
                if is.pdf.is_nan() || is.pdf <= 0.0 {
                    scratch.links.push(Link::plain(
                        walk::plus_emitted(weight * delta, emitted),
                        Rgb::ZERO,
                    ));
                    return;
                }
                // line 11: G + (f - g) / p with f = f_p * TraceRay (lines 9-10)
                let b = weight * (is.phase_value / is.pdf);
                let mut link = Link {
                    a: walk::plus_emitted(weight * (delta + is.G - is.g / is.pdf), emitted),
                    b,
                    // line 13: the record (direction, radiance), merged after the pass
                    record: Some((p, is.wi, is.phase_value)),
                    roulette: None,
                };
                s.beta *= b;
                let c = cache.radiance(is.wi, smc.settings.variant.cv);
                let alive = walk::roulette(s.depth, &mut s.beta, c, &mut link, sampler);
                scratch.links.push(link);
                if !alive {
                    return;
                }
                s.ray = Ray::new(p, is.wi);
                s.medium = Some(m);
                s.prev = Previous::singular(p);
            }
            // line 16: the background
            Event::Escape => {
                let a = weight * walk::escaped(scene, s.ray.d, &s.prev, s.depth);
                scratch.links.push(Link::plain(a, Rgb::ZERO));
                return;
            }
            Event::Surface { hit, medium: m } => {
                let st = walk::surface(scene, &hit, m, &mut s, smc.max_depth, sampler);
                let Some((w, next_ray, next_medium, next_prev)) = st.next else {
                    scratch.links.push(Link::plain(weight * st.a, Rgb::ZERO));
                    return;
                };
                let mut link = Link::plain(weight * st.a, weight * w);
                s.beta *= weight * w;
                let alive = walk::roulette(s.depth, &mut s.beta, Rgb::ZERO, &mut link, sampler);
                scratch.links.push(link);
                if !alive {
                    return;
                }
                s.ray = next_ray;
                s.medium = next_medium;
                s.prev = next_prev;
            }
        }
    }
}
// ANCHOR_END: fig2
