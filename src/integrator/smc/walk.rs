//! The parts of a camera path that SMC shares between its two estimators: the linear recursion
//! that turns a path into radiance records, surface vertices (next-event estimation with MIS,
//! as in the path tracer), delta lights at medium vertices, and emission found by chance.
//!
//! A path is a chain of links R_k = a_k + b_k R_{k+1}, where R_k is the estimate of the
//! radiance carried back along the k-th ray. At a medium vertex the combined estimator of
//! eq. (1) is a link: G + (f_p L - g) / p = (G - g / p) + (f_p / p) L. Solving the chain from
//! the end gives every R_{k+1}, the "radiance = TraceRay(position, direction)" of
//! [PWP08 Fig. 2 line 9], which becomes the record of vertex k.
//!
//! Lights. At medium vertices SMC samples light implicitly (the in-scattering integral
//! includes emitters hit by chance, as in [PWP08 sec. 5]); delta lights, which no direction can
//! hit, are added by a shadow ray. At surfaces next-event estimation and BSDF sampling are
//! combined by MIS exactly as in the path tracer, so emission reached after a medium vertex has
//! weight 1 and after a surface the power-heuristic weight.
//! Book: "SMC: the estimators".

use glam::Vec3;

use super::octree::Record;
use crate::bsdf::{Normals, TransportMode};
use crate::geometry::{offset_origin, shadow_distance, Hit, Ray};
use crate::integrator::path::power_heuristic;
use crate::math::Sampler;
use crate::scene::light::LightPointDraw;
use crate::scene::{Light, Scene};
use crate::spectrum::Rgb;

/// One link R_k = a_k + b_k R'_{k+1}; `record` is the vertex at the end of ray k whose
/// incoming radiance along `wi` is R'_{k+1}. After Russian roulette with control value c and
/// survival probability q (`roulette = Some((c, 1 / q))`, 1 / q = 0 when the path ended there),
/// R'_{k+1} = c + (R_{k+1} - c) / q; without it R'_{k+1} = R_{k+1}.
#[derive(Clone, Copy, Debug)]
pub struct Link {
    pub a: Rgb,
    pub b: Rgb,
    pub record: Option<(Vec3, Vec3, f32)>,
    pub roulette: Option<(Rgb, f32)>,
}

impl Link {
    /// A link without record.
    pub fn plain(a: Rgb, b: Rgb) -> Self {
        Link {
            a,
            b,
            record: None,
            roulette: None,
        }
    }
}

/// Per-thread scratch storage for a path's links (no allocation per sample).
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    pub links: Vec<Link>,
}

/// Solves the chain from its end (R after the last link is 0), appending one record per
/// medium vertex, and returns R_0, the pixel's radiance.
// ANCHOR: resolve
pub fn resolve(links: &[Link], records: &mut Vec<Record>) -> Rgb {
    let mut r = Rgb::ZERO;
    for link in links.iter().rev() {
        let mut ended = false;
        if let Some((c, inv_q)) = link.roulette {
            r = c + (r - c) * inv_q;
            ended = inv_q == 0.0;
        }
        if let Some((p, wi, phase_value)) = link.record {
            // a path ended by the roulette records nothing: c is the cache's own value
            if r.is_finite() && !ended {
                records.push(Record {
                    p,
                    wi,
                    radiance: r,
                    phase_value,
                });
            }
        }
        r = link.a + link.b * r;
    }
    r
}
// ANCHOR_END: resolve

/// Where the previous scattering happened, for the MIS weight of emission found by chance.
#[derive(Clone, Copy, Debug)]
pub struct Previous {
    pub p: Vec3,
    /// Solid-angle density of the direction sampled there.
    pub pdf_dir: f32,
    /// True when no light sampling at that vertex could have produced the direction: a
    /// primary ray, a Dirac BSDF lobe, or an SMC medium vertex (implicit light sampling).
    pub singular: bool,
}

impl Previous {
    pub fn singular(p: Vec3) -> Self {
        Previous {
            p,
            pdf_dir: 1.0,
            singular: true,
        }
    }
}

/// Radiance of the environment along an escaping ray after `depth` scattering vertices,
/// MIS-weighted against next-event estimation at the previous vertex (none below the scene's
/// `min_depth`).
pub fn escaped(scene: &Scene, d: Vec3, prev: &Previous, depth: u32) -> Rgb {
    let Some(e) = scene.environment else {
        return Rgb::ZERO;
    };
    if depth < scene.min_depth() {
        return Rgb::ZERO;
    }
    let Light::Environment(env) = &scene.lights[e as usize] else {
        return Rgb::ZERO;
    };
    let w = if prev.singular {
        1.0
    } else {
        power_heuristic(prev.pdf_dir, scene.light_pmf(e) * env.pdf(d))
    };
    env.radiance(d) * w
}

/// The emission L_e,V0 of the medium at the collision `prop` sampled, by the collision
/// estimator T L_e,V0 / p(t) (eq. 3's source term; [PWP08 eq. 4, 7] write it sigma_a L_e, the
/// same quantity in the paper's units): unbiased for the integral of T L_e,V0 along the flight
/// wherever the collision density is positive, as in the path tracer. Weight 1: SMC samples
/// no emitting medium as a light, so the walk is its only estimator. Zero (and nothing read)
/// unless the collision is in an emitting medium.
pub fn emitted(scene: &Scene, prop: &crate::scene::Propagation) -> Rgb {
    let crate::scene::Event::Medium { p, medium: m, .. } = prop.event else {
        return Rgb::ZERO;
    };
    let med = &scene.media[m as usize];
    if !med.emits() || prop.pdf.is_nan() || prop.pdf <= 0.0 {
        return Rgb::ZERO;
    }
    prop.transmittance * med.emission(p) / prop.pdf
}

/// `a` with the emission `e` added; `a` itself, bit for bit, when nothing glows (0 + -0 would
/// be +0: the images of scenes without emission stay what they were).
#[inline]
pub fn plus_emitted(a: Rgb, e: Rgb) -> Rgb {
    if e == Rgb::ZERO {
        a
    } else {
        e + a
    }
}

/// The direct light of every delta light (point, spot, directional) at `p` in `medium`, with
/// `scatter(wi)` the phase function or cosine factor: these lights cannot be found by chance.
pub fn delta_lights(
    scene: &Scene,
    p: Vec3,
    medium: Option<u32>,
    sampler: &mut Sampler,
    scatter: impl Fn(Vec3) -> f32,
) -> Rgb {
    let mut l = Rgb::ZERO;
    for light in scene.lights.iter().filter(|l| l.is_delta()) {
        let u = sampler.next_2d();
        let Some(ls) = light.sample_li(&scene.prims, p, (u, 0.0), LightPointDraw::Area) else {
            continue;
        };
        let f = scatter(ls.wi);
        if f <= 0.0 || ls.value == Rgb::ZERO {
            continue;
        }
        let dist = if ls.dist.is_infinite() {
            f32::INFINITY
        } else {
            shadow_distance(p, ls.p)
        };
        let tr = scene.transmittance(p, ls.wi, dist, medium, sampler);
        l += f * ls.value * tr / ls.pdf;
    }
    l
}

/// A camera path between two vertices: the ray it follows, the medium that ray starts in, the
/// last scattering vertex (for the MIS weight of emission found by chance), the throughput and
/// the number of scattering vertices so far. What both estimators' walks carry from vertex to
/// vertex, bundled so that they and [`surface`] take one argument for it.
#[derive(Clone, Copy, Debug)]
pub struct State {
    pub ray: Ray,
    pub medium: Option<u32>,
    pub prev: Previous,
    pub beta: Rgb,
    pub depth: u32,
}

impl State {
    /// A path starting along `ray` in `medium` with throughput `beta`, its origin a singular
    /// vertex (a primary ray or a meter point).
    pub fn start(ray: Ray, medium: Option<u32>, beta: Rgb) -> Self {
        State {
            ray,
            medium,
            prev: Previous::singular(ray.o),
            beta,
            depth: 0,
        }
    }
}

/// What a surface vertex contributes: emitted (MIS-weighted) plus next-event radiance `a`, and
/// the continuation (BSDF weight, next ray, its medium, the new previous vertex) if any.
pub struct SurfaceStep {
    pub a: Rgb,
    pub next: Option<(Rgb, Ray, Option<u32>, Previous)>,
}

/// A surface vertex `hit` reached by `state`'s ray in `medium`: emission found by chance, NEE
/// with MIS, BSDF sampling. `state.depth` counts scattering vertices and is incremented here
/// when the surface scatters; the rest of `state` is read only (the caller moves it on).
// ANCHOR: surface
pub fn surface(
    scene: &Scene,
    hit: &Hit,
    medium: Option<u32>,
    state: &mut State,
    max_depth: u32,
    sampler: &mut Sampler,
) -> SurfaceStep {
    let (ray, prev, depth) = (&state.ray, &state.prev, &mut state.depth);
    let shape = scene.shape_of(hit);
    let n = hit.ng;
    let mut a = Rgb::ZERO;
    if let Some(li) = shape.light {
        if ray.d.dot(n) < 0.0 && *depth >= scene.min_depth() {
            let light = &scene.lights[li as usize];
            if matches!(light, Light::Area { .. }) {
                let radiance = light.area_radiance(&scene.prims, hit.prim, hit.p);
                let w = if prev.singular {
                    1.0
                } else {
                    let pdf_light = scene.light_pmf(li)
                        * scene.lights[li as usize].pdf_li(
                            &scene.prims,
                            prev.p,
                            (hit.p, n, hit.prim),
                            LightPointDraw::Area,
                        );
                    power_heuristic(prev.pdf_dir, pdf_light)
                };
                a += radiance * w;
            }
        }
    }
    let Some(bsdf) = scene.bsdf_at(hit.prim, hit.p) else {
        return SurfaceStep { a, next: None };
    };
    if *depth >= max_depth {
        return SurfaceStep { a, next: None };
    }
    *depth += 1;
    let wo = -ray.d;
    let nn = Normals {
        ng: n,
        ns: scene.shading_normal(hit),
    };
    if bsdf.has_regular_lobe() {
        let towards = |wi: Vec3| shape.medium_across(wo, wi, n, medium);
        a += crate::integrator::path::next_event(scene, hit.p, Some(n), towards, sampler, |wi| {
            let f = bsdf.eval_shaded(wo, wi, nn, TransportMode::Radiance);
            (f * wi.dot(n).abs(), bsdf.pdf_shaded(wo, wi, nn))
        });
    }
    let u = sampler.next_2d();
    let uc = sampler.next_f32();
    let Some(bs) = bsdf.sample_shaded(wo, nn, u, uc, TransportMode::Radiance) else {
        return SurfaceStep { a, next: None };
    };
    if bs.pdf <= 0.0 {
        return SurfaceStep { a, next: None };
    }
    let next_medium = shape.medium_across(wo, bs.wi, n, medium);
    let prev = Previous {
        p: hit.p,
        pdf_dir: bs.pdf,
        singular: bs.lobe.is_singular(),
    };
    let ray = Ray::new(offset_origin(hit.p, n, bs.wi), bs.wi);
    SurfaceStep {
        a,
        next: Some((bs.weight(n), ray, next_medium, prev)),
    }
}
// ANCHOR_END: surface

/// Russian roulette after a scattering vertex, with a control value: survive with
/// q = min(max beta, 0.95); the radiance R along the continuation is then estimated by
/// c + (R - c) / q if the path survives and by c if it ends, unbiased for any c
/// (E = c + q (E[R] - c) / q = E[R]). This is eq. (1) applied to the decision to continue.
/// With c = 0 it is the path tracer's roulette; SMC passes the cache's reconstruction L~(wi),
/// so that ending a path costs only the cache's error instead of the whole radiance.
/// DEVIATION: the paper does not discuss path termination; plain roulette (c = 0) would leave
/// a variance floor that no adaptation removes (see the experiments chapter).
/// Returns false to end the path.
// ANCHOR: roulette
#[inline]
pub fn roulette(
    depth: u32,
    beta: &mut Rgb,
    c: Rgb,
    link: &mut Link,
    sampler: &mut Sampler,
) -> bool {
    // ASSIGNMENT: cv_roulette
    use crate::integrator::path::{RR_MAX_SURVIVAL, RR_START_DEPTH};
    if depth < RR_START_DEPTH {
        return true;
    }
    let q = beta.abs().max_element().min(RR_MAX_SURVIVAL);
    if q.is_nan() || sampler.next_f32() >= q {
        link.roulette = Some((c, 0.0));
        return false;
    }
    link.roulette = Some((c, 1.0 / q));
    *beta /= q;
    true
    // END ASSIGNMENT
}
// ANCHOR_END: roulette
