//! The volumetric path tracer: the Neumann series (Pauly, Kollig, Keller 2000, eq. 4) made
//! into a random walk. Each step propagates the ray by Table 1 (a medium vertex or the next
//! surface, through null boundaries), estimates direct light by next-event estimation with a
//! transmittance-weighted shadow ray, and continues by BSDF or phase-function sampling. The two
//! ways of reaching a light (light sampling, scattering sampling) are combined by multiple
//! importance sampling with the power heuristic; Russian roulette ends long paths without bias.
//! Book: "The Neumann series and the path tracer".

use glam::Vec3;

use crate::bsdf::{Normals, TransportMode};
use crate::geometry::{offset_origin, shadow_distance, Ray};
use crate::math::distribution::ONE_MINUS_EPSILON;
use crate::math::{warp, Frame, Sampler};
use crate::medium::Medium;
use crate::path::distance::RayMedia;
use crate::path::technique::{local_scatter_pdf, LocalSampling, ScatterSample};
use crate::path::{Vertex, VertexKind};
use crate::scene::halo::HaloMixture;
use crate::scene::light::LightPointDraw;
use crate::scene::{Event, IrradianceMeter, LightSelection, Scene};
use crate::spectrum::Rgb;

/// Power heuristic with beta = 2 (Veach 1997): the weight of the strategy with density `a`.
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    // ASSIGNMENT: power_heuristic
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
    // END ASSIGNMENT
}

pub use crate::path::technique::{RR_MAX_SURVIVAL, RR_START_DEPTH};

/// The number of scattering vertices after which the path tracer starts Russian roulette: 5,
/// counted as the bidirectional walks count theirs (only vertices with a density,
/// [`RR_START_DEPTH`]); Mitsuba 3's `rr_depth` is 5 too, counted over every vertex. On the fog
/// box a later start trades time for variance almost exactly (the book's "Measuring a
/// renderer": from 3, 5 and 8 the efficiencies agree within 5%), and from 5 one sample has no
/// more error than Mitsuba's `volpath`. The bidirectional walks and SMC keep
/// [`RR_START_DEPTH`].
pub const PATH_RR_START_DEPTH: u32 = 5;

/// The weight of the distance strategy with density `a` against the other's `b`: the balance
/// heuristic (Veach 1997), a / (a + b).
#[inline]
pub fn distance_mis(a: f32, b: f32) -> f32 {
    if a + b > 0.0 && (a + b).is_finite() {
        a / (a + b)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// The path tracer's parameters.
#[derive(Clone, Debug)]
pub struct PathTracer<'t> {
    /// Maximum number of scattering vertices (surface or medium) between sensor and light.
    pub max_depth: u32,
    /// How distances along the walk's rays are sampled for the light scattered toward lights.
    pub distance: DistanceSampling,
    /// How next-event estimation picks a light (`[render] light_selection`).
    pub selection: LightSelection,
    /// How next-event estimation draws a point on an area light (`[render] light_point`);
    /// by area whatever this says when distances are sampled by `equiangular-mis`
    /// ([`PathTracer::light_draw`]).
    pub light_point: LightPointDraw,
    /// Next-event estimation toward emitting media (`[render] volume_next_event`); without
    /// it their emission is collected along free flights alone, with MIS weight 1.
    pub volume_next_event: bool,
    /// The technique that guides scattering directions (Kristensen 2010, sec. 5.3: the
    /// mixtures of eq. 5.18 and its medium form, the guided choice at glass, guided roulette),
    /// when one does; `None`: the BSDF's and phase function's own sampling, as always.
    pub guide: Option<&'t dyn LocalSampling>,
    /// The cones toward lights' halos mixed into the phase function at medium vertices and
    /// into the BSDF's sampling at surfaces without a Dirac lobe (`[render] halo_cone`),
    /// when no guide samples the directions; `None`: their own sampling alone.
    pub halo: Option<HaloMixture>,
}

/// How the path tracer samples the distance to a medium vertex on each ray of its walk, for
/// the light that vertex gathers by next-event estimation (`[render] distance`, `--distance`; book: "Table 1: homogeneous
/// media", section "Equiangular sampling").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum DistanceSampling {
    /// Table 1's free flight alone.
    #[default]
    FreeFlight,
    /// Free flight and equiangular sampling toward a light point (Kulla and Fajardo 2012) on
    /// every ray of the walk (after each surface or medium scattering), one sample of each,
    /// their next-event estimates combined by the balance heuristic; the walk continues from
    /// the free-flight sample only.
    EquiangularMis,
}

crate::option_value!(DistanceSampling, "distance sampling");

/// Where the previous scattering happened, for the MIS weight of emission found by chance.
#[derive(Clone, Copy)]
struct Previous {
    p: Vec3,
    /// The surface normal there (`None` in a medium and at the camera): the light selection
    /// at `p` depends on it, and its probability enters the MIS weight.
    n: Option<Vec3>,
    /// Solid-angle density of the direction sampled there.
    pdf_dir: f32,
    /// True when that direction was a Dirac (no light sampling could have produced it) or the
    /// ray is primary (the camera sees emitters directly).
    singular: bool,
}

impl<'t> PathTracer<'t> {
    pub fn new(max_depth: Option<u32>) -> Self {
        PathTracer {
            max_depth: max_depth.unwrap_or(u32::MAX),
            distance: DistanceSampling::FreeFlight,
            selection: LightSelection::Power,
            light_point: LightPointDraw::default(),
            volume_next_event: true,
            guide: None,
            halo: None,
        }
    }

    /// This path tracer sampling its scattering directions from `technique` where it guides
    /// them ([`LocalSampling::guides_scattering`]), else as before.
    pub fn with_guide(mut self, technique: &'t dyn LocalSampling) -> Self {
        self.guide = technique.guides_scattering().then_some(technique);
        self
    }

    /// The solid-angle density with which the walk samples `wi` at the surface or medium
    /// vertex `v` reached from `wo`: the guide's mixture (c1 p_fs + c2 p_Li, eq. 5.18, or
    /// c1 p_fp + c2 p_Li in a medium) where it guides `v`, else the BSDF's or phase function's
    /// own. Every MIS weight of the walk against a direction it could have sampled (next-event
    /// estimation toward lights and emitting media, the equiangular estimate's light sample)
    /// takes this density, the partner of the sampled direction's [`ScatterSample::pdf`].
    // ANCHOR: path_scatter_pdf
    pub fn scatter_pdf(&self, scene: &Scene, v: &Vertex, wo: Vec3, wi: Vec3) -> f32 {
        match self.guide {
            Some(tech) => tech.scatter_pdf(scene, v, wo, wi, TransportMode::Radiance),
            None => local_scatter_pdf(scene, v, wo, wi).unwrap_or(0.0),
        }
    }
    // ANCHOR_END: path_scatter_pdf

    /// The walk's direction at the surface or medium vertex `v` reached from `wo`: from the
    /// guide where one is installed (its mixture, the guided lobe choice at glass), with the
    /// density [`PathTracer::scatter_pdf`] gives; `None` ends the walk.
    pub fn sample_scatter(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        sampler: &mut Sampler,
    ) -> Option<ScatterSample> {
        let tech = self.guide.unwrap_or(&crate::path::technique::PLAIN);
        tech.sample_scatter(scene, v, wo, TransportMode::Radiance, sampler)
            .filter(|ss| ss.pdf > 0.0)
    }

    /// This path tracer drawing, with probability `share`, the directions of medium vertices
    /// and of surfaces without a Dirac lobe in the cone toward a light's halo (0: never); the
    /// guide, where one is installed, samples them instead.
    pub fn with_halo_cone(mut self, scene: &Scene, share: f32) -> Self {
        self.halo = HaloMixture::new(scene, share);
        self
    }

    /// The walk's direction sampling at medium point `p` of medium `m` reached from `wo`, as
    /// MIS weights against it need it: each direction's phase function value and density
    /// (the guide's mixture, the halo mixture or the phase function's own).
    fn medium_scatter<'a>(
        &'a self,
        scene: &'a Scene,
        (p, m): (Vec3, u32),
        wo: Vec3,
    ) -> impl Fn(Vec3) -> (Rgb, f32) + 'a {
        let phase = scene.media[m as usize].phase();
        let v = self.guide.map(|_| Self::medium_vertex_at(p, m));
        move |wi: Vec3| {
            let f = phase.eval(wo, wi);
            let pdf = match (&v, &self.halo) {
                (Some(v), _) => self.scatter_pdf(scene, v, wo, wi),
                (None, Some(halo)) => halo.pdf(scene, &self.selection, (p, None), f, wi),
                (None, None) => f,
            };
            (Rgb::splat(f), pdf)
        }
    }

    /// The walk's direction at medium point `p` of medium `m` reached from `wo`, drawn as
    /// [`PathTracer::medium_scatter`] gives its density; `None` ends the walk.
    fn sample_medium_scatter(
        &self,
        scene: &Scene,
        (p, m): (Vec3, u32),
        wo: Vec3,
        sampler: &mut Sampler,
    ) -> Option<ScatterSample> {
        let phase = scene.media[m as usize].phase();
        if self.guide.is_some() {
            let v = Self::medium_vertex_at(p, m);
            return self.sample_scatter(scene, &v, wo, sampler);
        }
        let Some(halo) = &self.halo else {
            return Some(ScatterSample::from_phase(
                phase.sample(wo, sampler.next_2d()),
            ));
        };
        let (wi, f) = match halo.draw(scene, &self.selection, (p, None), sampler) {
            Ok(wi) => (wi, phase.eval(wo, wi)),
            Err(u) => {
                let ps = phase.sample(wo, u);
                (ps.wi, ps.value)
            }
        };
        Some(ScatterSample {
            wi,
            value: Rgb::splat(f),
            pdf: halo.pdf(scene, &self.selection, (p, None), f, wi),
            lobe: crate::bsdf::Lobe::Regular,
            lhat: None,
        })
    }

    /// The medium vertex at `p` in medium `m`, for the guide's map lookup.
    fn medium_vertex_at(p: Vec3, m: u32) -> Vertex {
        Vertex::new(
            VertexKind::Medium { medium: m },
            p,
            Vec3::ZERO,
            Some(m),
            Some(m),
        )
    }

    /// This path tracer with or without next-event estimation toward emitting media.
    pub fn with_volume_next_event(mut self, on: bool) -> Self {
        self.volume_next_event = on;
        self
    }

    /// This path tracer drawing area lights' points for next-event estimation by `draw`.
    pub fn with_light_point(mut self, draw: LightPointDraw) -> Self {
        self.light_point = draw;
        self
    }

    /// How next-event estimation draws light points: as `light_point` says, but by area with
    /// `equiangular-mis`, whose distance weights compare densities of a light point drawn
    /// before the distance, that is without the reference point.
    pub fn light_draw(&self) -> LightPointDraw {
        match self.distance {
            DistanceSampling::FreeFlight => self.light_point,
            DistanceSampling::EquiangularMis => LightPointDraw::Area,
        }
    }

    /// This path tracer picking lights for next-event estimation by `selection`.
    pub fn with_light_selection(mut self, selection: LightSelection) -> Self {
        self.selection = selection;
        self
    }

    /// This path tracer sampling its rays' distances by `distance`.
    pub fn with_distance(mut self, distance: DistanceSampling) -> Self {
        self.distance = distance;
        self
    }

    /// Radiance arriving at the camera along `ray`, which starts in `medium`.
    pub fn radiance(
        &self,
        scene: &Scene,
        ray: Ray,
        medium: Option<u32>,
        sampler: &mut Sampler,
    ) -> Rgb {
        let prev = Previous {
            p: ray.o,
            n: None,
            pdf_dir: 1.0,
            singular: true,
        };
        let w = WalkState::new(ray, medium, Rgb::ONE, prev);
        self.walk(scene, w, sampler)
    }

    /// The equiangular strategy's estimate of the light scattered once on the ray
    /// `media.ray` (per unit throughput before it): a light and a point y on it as next-event
    /// estimation draws them, a distance toward y (Kulla and Fajardo 2012), and that light
    /// sample's estimate there, weighted by the balance heuristic against the free-flight
    /// density of the same distance.
    // ANCHOR: equiangular_estimate
    fn equiangular_estimate(&self, scene: &Scene, media: &RayMedia, sampler: &mut Sampler) -> Rgb {
        if scene.lights.is_empty() {
            return Rgb::ZERO;
        }
        // a light chosen at the ray's origin (the vertex is not known yet), half the time by
        // power: a one-sided light facing away from the origin gets no share of a tree there,
        // yet may light the ray's points, where the free-flight vertex's weight counts on it
        let Some((l, pmf, u_prim)) = self.equiangular_light(scene, media.ray.o, sampler) else {
            return Rgb::ZERO;
        };
        let (u, u_t) = (sampler.next_2d(), sampler.next_f32());
        let light = &scene.lights[l];
        let Some(at) = light.sample_point(&scene.prims, u, u_prim) else {
            return Rgb::ZERO;
        };
        let Some((i, t, pdf_eq)) = media.sample_equiangular(at.p, u_t) else {
            return Rgb::ZERO;
        };
        let (p, m) = (media.ray.at(t), media.spans()[i].medium);
        let Some(ls) = light.li_towards(&scene.prims, p, &at) else {
            return Rgb::ZERO;
        };
        let medium = &scene.media[m as usize];
        let mis = distance_mis(pdf_eq, media.free_flight_pdf(scene, i, t));
        // transmittance to the vertex times sigma_s there, over the equiangular density
        let tr = media.transmittance(scene, i, t, sampler);
        let beta = tr * medium.sigma_s(p) * (mis / pdf_eq);
        // the MIS partner is the walk's direction sampling at p (the guide's or halo mixture)
        let scatter = self.medium_scatter(scene, (p, m), -media.ray.d);
        // the MIS weight against phase sampling at p takes the selection's probability at p,
        // as the walk's emission found from p does; the estimate divides by the one drawn
        let pmf_here = self.selection.pmf(scene, p, None, l as u32);
        if pmf_here <= 0.0 {
            return Rgb::ZERO;
        }
        let est =
            light_sample_estimate(scene, p, None, |_| Some(m), sampler, scatter, &ls, pmf_here);
        beta * est * (pmf_here / pmf)
    }
    // ANCHOR_END: equiangular_estimate

    /// The equiangular estimate's light, its probability and the number left for its point:
    /// the selection at `o` (the light tree or power) mixed half and half with power, so
    /// that every light with power has a share whatever `o` sees of it.
    fn equiangular_light(
        &self,
        scene: &Scene,
        o: Vec3,
        sampler: &mut Sampler,
    ) -> Option<(usize, f32, f32)> {
        let u = sampler.next_f32();
        let power = matches!(self.selection, LightSelection::Power);
        if power {
            return self.selection.sample(scene, o, None, u);
        }
        // the selection's probability of a light it sampled is the one it returned, bit for
        // bit what `pmf` evaluates (`tests/spec/scene/light_tree.rs`)
        let (l, pmf_sel, rem) = if u < 0.5 {
            self.selection.sample(scene, o, None, 2.0 * u)?
        } else {
            let (l, _, rem) = scene
                .light_distr
                .sample((2.0 * u - 1.0).min(ONE_MINUS_EPSILON));
            (l, self.selection.pmf(scene, o, None, l as u32), rem)
        };
        let pmf = 0.5 * (pmf_sel + scene.light_pmf(l as u32));
        Some((l, pmf, rem))
    }

    /// One sample of a meter's mean irradiance: a point uniform on the meter, then the meter
    /// treated as a vertex whose "BSDF" is 1 on its normal side, so that integrating it against
    /// L cos gives irradiance (light sampling there, then a cosine-sampled continuation).
    pub fn meter_irradiance(
        &self,
        scene: &Scene,
        meter: &IrradianceMeter,
        sampler: &mut Sampler,
    ) -> Rgb {
        let n = meter.normal();
        let (p, _) = crate::geometry::Primitive::Quad(meter.quad).sample_area(sampler.next_2d());
        let mut l = next_event_weighted(
            scene,
            (&self.selection, self.light_draw()),
            p,
            None,
            |_| meter.medium,
            sampler,
            |wi| {
                let c = wi.dot(n);
                if c > 0.0 {
                    (Rgb::splat(c), c * std::f32::consts::FRAC_1_PI)
                } else {
                    (Rgb::ZERO, 0.0)
                }
            },
            |_, _| 1.0,
        );
        l += self.volume_nee(
            scene,
            (p, None),
            |_| meter.medium,
            sampler,
            |wi| {
                let c = wi.dot(n).max(0.0);
                (Rgb::splat(c), c * std::f32::consts::FRAC_1_PI)
            },
        );
        let local = warp::cosine_hemisphere(sampler.next_2d());
        if local.z <= 0.0 {
            return l;
        }
        let wi = Frame::from_normal(n).to_world(local);
        let prev = Previous {
            p,
            n: None,
            pdf_dir: local.z * std::f32::consts::FRAC_1_PI,
            singular: false,
        };
        // f cos / pdf = cos / (cos / pi) = pi
        let w = WalkState::new(
            Ray::new(p, wi),
            meter.medium,
            Rgb::splat(std::f32::consts::PI),
            prev,
        );
        l += self.walk(scene, w, sampler);
        l
    }

    /// The random walk from `w.ray` with throughput `w.beta` after `w.depth` scattering vertices.
    /// With `distance = "equiangular-mis"` every ray of it also gets the equiangular estimate,
    /// the partner of its free-flight vertex's next-event estimate.
    // ANCHOR: walk
    fn walk(&self, scene: &Scene, mut w: WalkState, sampler: &mut Sampler) -> Rgb {
        let mut l = Rgb::ZERO;
        // only emission found by a collision reads a propagation's transmittance and pdf
        let weight_only = !scene.media.iter().any(Medium::emits);
        loop {
            // equiangular sampling on this ray, if a vertex on it may still scatter
            // the camera's rays see through hidden emitters until the first scattering vertex
            let from_camera = w.depth == 0;
            let media = (self.distance == DistanceSampling::EquiangularMis
                && w.depth < self.max_depth)
                .then(|| RayMedia::collect_seen(scene, w.ray, (w.lead, w.medium), from_camera));
            if let Some(media) = &media {
                l += w.beta * self.equiangular_estimate(scene, media, sampler);
            }
            let (event, weight) =
                self.propagate(scene, &w, media.as_ref(), weight_only, sampler, &mut l);
            w.beta *= weight;
            if w.beta == Rgb::ZERO {
                break;
            }
            let go_on = match event {
                Event::Escape => {
                    if w.depth >= scene.min_depth() {
                        l += escaped(scene, &self.selection, &w);
                    }
                    false
                }
                Event::Medium {
                    p, t, medium: m, ..
                } => {
                    // the free-flight partner of this ray's equiangular estimate
                    let on_ray = media.as_ref().and_then(|c| Some((c, c.locate(t, m)?, t)));
                    self.medium_vertex(scene, &mut w, (p, m), on_ray, sampler, &mut l)
                }
                Event::Surface { hit, medium: m } => {
                    self.surface_vertex(scene, &mut w, &hit, m, sampler, &mut l)
                }
            };
            if !go_on {
                break;
            }
            if !w.prev.singular {
                w.rough += 1;
            }
            // Russian roulette: survive with q, divide by q (unbiased: q * X / q = X)
            if w.rough >= PATH_RR_START_DEPTH {
                let q = self.survival(&w);
                if sampler.next_f32() >= q || q.is_nan() {
                    break;
                }
                w.beta /= q;
            }
        }
        l
    }

    /// Table 1 through media and null boundaries from the walk's ray (along the segments the
    /// equiangular spans were read from, when it kept them all): the event and the throughput
    /// factor, the emission of an emitting medium collided in added to `l`. With `weight_only`
    /// (no medium emits) nothing reads the transmittance or pdf of the flights (the equiangular
    /// MIS weights evaluate their own free-flight densities), so only the weight is asked for
    /// ([`Scene::propagate_weight_from`]: no exact optical depth in grey tracked media).
    fn propagate(
        &self,
        scene: &Scene,
        w: &WalkState,
        media: Option<&RayMedia>,
        weight_only: bool,
        sampler: &mut Sampler,
        l: &mut Rgb,
    ) -> (Event, Rgb) {
        let from_camera = w.depth == 0;
        let segs = media.and_then(RayMedia::segments);
        if weight_only {
            let prop = match segs {
                Some(segs) => scene.propagate_weight_along(w.ray, segs.iter().copied(), sampler),
                None => scene.propagate_weight_from(w.ray, w.lead, w.medium, from_camera, sampler),
            };
            return (prop.event(), prop.weight());
        }
        let prop = match segs {
            Some(segs) => scene.propagate_along(w.ray, segs.iter().copied(), sampler),
            None => scene.propagate_from(w.ray, w.lead, w.medium, from_camera, sampler),
        };
        if let Event::Medium { p, medium: m, .. } = prop.event {
            if scene.media[m as usize].emits() {
                let nee = self.volume_next_event;
                *l += volume_emission_found(scene, w, &prop, (p, m), nee);
            }
        }
        (prop.event, prop.weight())
    }
    // ANCHOR_END: walk

    /// A medium vertex at `p` in medium `m`: next-event estimation into `l`, then a direction
    /// from the phase function; false ends the walk. `on_ray` is the ray's spans with the
    /// vertex's span and ray parameter when the equiangular strategy shares its estimate.
    fn medium_vertex(
        &self,
        scene: &Scene,
        w: &mut WalkState,
        (p, m): (Vec3, u32),
        on_ray: Option<(&RayMedia, usize, f32)>,
        sampler: &mut Sampler,
        l: &mut Rgb,
    ) -> bool {
        if w.depth >= self.max_depth {
            return false;
        }
        w.depth += 1;
        let wo = -w.ray.d;
        let pdf_ff = on_ray.map_or(0.0, |(c, i, t)| c.free_flight_pdf(scene, i, t));
        // the balance heuristic against equiangular sampling toward the light point drawn
        // (which never samples infinite lights: weight 1 for them)
        let mis = |light: usize, ls: &crate::scene::light::LightSample| match on_ray {
            Some((c, i, t)) if !scene.lights[light].is_infinite() => {
                distance_mis(pdf_ff, c.equiangular_pdf(ls.p, i, t))
            }
            _ => 1.0,
        };
        // f-hat = sigma_s f_p; sigma_s/pdf is already in beta (FreeFlight::weight)
        let scatter = self.medium_scatter(scene, (p, m), wo);
        *l += w.beta
            * next_event_weighted(
                scene,
                (&self.selection, self.light_draw()),
                p,
                None,
                |_| Some(m),
                sampler,
                &scatter,
                mis,
            );
        *l += w.beta * self.volume_nee(scene, (p, None), |_| Some(m), sampler, &scatter);
        // no early stop here: a direction sampled at the last allowed vertex can still
        // reach an emitter, the MIS partner of the light sample above
        let Some(ps) = self.sample_medium_scatter(scene, (p, m), wo, sampler) else {
            return false;
        };
        if ps.pdf <= 0.0 {
            return false;
        }
        w.beta *= ps.value / ps.pdf;
        w.lhat = ps.lhat;
        w.prev = Previous {
            p,
            n: None,
            pdf_dir: ps.pdf,
            singular: false,
        };
        w.ray = Ray::new(p, ps.wi);
        w.lead = 0.0;
        w.medium = Some(m);
        true
    }

    /// A surface vertex at `hit` (medium `m` on the arriving side): emission found by chance
    /// and next-event estimation into `l`, then a direction from the BSDF; false ends the walk.
    fn surface_vertex(
        &self,
        scene: &Scene,
        w: &mut WalkState,
        hit: &crate::geometry::Hit,
        m: Option<u32>,
        sampler: &mut Sampler,
        l: &mut Rgb,
    ) -> bool {
        let shape = scene.shape_of(hit);
        let n = hit.ng;
        if let Some(li) = shape.light {
            if w.ray.d.dot(n) < 0.0 && w.depth >= scene.min_depth() {
                let lights = (&self.selection, self.light_draw());
                let Some(e) = emission_found(scene, lights, w, hit, li) else {
                    return false;
                };
                *l += e;
            }
        }
        let Some(bsdf) = scene.bsdf_at(hit.prim, hit.p) else {
            return false;
        };
        if w.depth >= self.max_depth {
            return false;
        }
        w.depth += 1;
        let wo = -w.ray.d;
        let nn = Normals {
            ng: n,
            ns: scene.shading_normal(hit),
        };
        let v = self.guide.map(|_| Vertex::on_surface(scene, hit, m));
        let surface_halo = self.halo.as_ref().filter(|_| !bsdf.has_dirac_lobe());
        // the regular lobe's light by next-event estimation; a Dirac lobe's only by sampling
        if bsdf.has_regular_lobe() {
            let towards = |wi: Vec3| shape.medium_across(wo, wi, n, m);
            let scatter = |wi: Vec3| {
                let f = bsdf.eval_shaded(wo, wi, nn, TransportMode::Radiance);
                let own = || bsdf.pdf_shaded(wo, wi, nn);
                let pdf = match (&v, surface_halo) {
                    (Some(v), _) => self.scatter_pdf(scene, v, wo, wi),
                    (None, Some(h)) => h.pdf(scene, &self.selection, (hit.p, Some(n)), own(), wi),
                    (None, None) => own(),
                };
                (f * wi.dot(n).abs(), pdf)
            };
            let sel = (&self.selection, self.light_draw());
            let no_weight = |_: usize, _: &_| 1.0;
            *l += w.beta
                * next_event_weighted(
                    scene,
                    sel,
                    hit.p,
                    Some(n),
                    towards,
                    sampler,
                    scatter,
                    no_weight,
                );
            let to = (hit.p, Some(n));
            *l += w.beta * self.volume_nee(scene, to, towards, sampler, scatter);
        }
        let bs = match &v {
            Some(v) => self.sample_scatter(scene, v, wo, sampler).map(|ss| {
                w.lhat = ss.lhat;
                ss.as_bsdf_sample()
            }),
            None => match surface_halo {
                Some(h) => {
                    let at = (hit.p, Some(n));
                    let drawn = h.draw(scene, &self.selection, at, sampler);
                    let uc = sampler.next_f32();
                    // a BSDF without a Dirac lobe samples by its whole density
                    let own = match drawn {
                        Ok(wi) => Some(crate::bsdf::BsdfSample {
                            wi,
                            value: bsdf.eval_shaded(wo, wi, nn, TransportMode::Radiance),
                            pdf: bsdf.pdf_shaded(wo, wi, nn),
                            lobe: crate::bsdf::Lobe::Regular,
                        }),
                        Err(u) => bsdf.sample_shaded(wo, nn, u, uc, TransportMode::Radiance),
                    };
                    own.map(|bs| crate::bsdf::BsdfSample {
                        pdf: h.pdf(scene, &self.selection, at, bs.pdf, bs.wi),
                        ..bs
                    })
                }
                None => {
                    let u = sampler.next_2d();
                    let uc = sampler.next_f32();
                    bsdf.sample_shaded(wo, nn, u, uc, TransportMode::Radiance)
                }
            },
        };
        let Some(bs) = bs else {
            return false;
        };
        if bs.pdf <= 0.0 {
            return false;
        }
        w.beta *= bs.weight(n);
        w.eta_scale /= bsdf.radiance_scale(wo, bs.wi, n);
        // crossing the surface (refraction) may change the medium
        w.medium = shape.medium_across(wo, bs.wi, n, m);
        w.prev = Previous {
            p: hit.p,
            n: Some(n),
            pdf_dir: bs.pdf,
            singular: bs.lobe.is_singular(),
        };
        w.ray = Ray::new(offset_origin(hit.p, n, bs.wi), bs.wi);
        w.lead = (w.ray.o - hit.p).dot(bs.wi);
        true
    }
}

impl PathTracer<'_> {
    /// Russian roulette's survival probability after the walk's latest scattering: the
    /// throughput rule, or the guide's (sec. 5.3.4) where it guided that direction and guided
    /// roulette is on (`--guide-roulette`). Both read the throughput without the eta^2 of the
    /// refractions so far (`eta_scale`): inside glass a radiance path's throughput is 1/eta^2
    /// of what it will be once out, and the roulette would end most paths for a factor their
    /// exit restores (Mitsuba 3's `volpath` and pbrt-v4 do the same).
    fn survival(&self, w: &WalkState) -> f32 {
        let throughput = w.beta.max_element() * w.eta_scale;
        let plain = throughput.min(RR_MAX_SURVIVAL);
        let Some(tech) = self.guide else {
            return plain;
        };
        let ratio = throughput / w.beta_start;
        tech.roulette_survival(w.lhat, ratio, RR_MAX_SURVIVAL)
            .unwrap_or(plain)
    }

    /// [`volume_next_event`] when it is on, else nothing (and no random number drawn).
    fn volume_nee(
        &self,
        scene: &Scene,
        at: (Vec3, Option<Vec3>),
        medium: impl Fn(Vec3) -> Option<u32>,
        sampler: &mut Sampler,
        scatter: impl Fn(Vec3) -> (Rgb, f32),
    ) -> Rgb {
        if !self.volume_next_event {
            return Rgb::ZERO;
        }
        volume_next_event(scene, at, medium, sampler, scatter)
    }
}

/// The state a path-tracing walk carries from vertex to vertex.
struct WalkState {
    ray: Ray,
    medium: Option<u32>,
    beta: Rgb,
    /// Scattering vertices so far.
    depth: u32,
    /// Of those, the vertices whose direction was drawn from a lobe with a density (a Dirac
    /// lobe's is not): Russian roulette starts once there are [`PATH_RR_START_DEPTH`].
    rough: u32,
    prev: Previous,
    /// Distance between the scattering vertex and the lifted ray origin.
    lead: f32,
    /// The largest channel of the throughput the walk started with (guided roulette's beta_0).
    beta_start: f32,
    /// The guide's Lhat of the latest sampled direction, where it guided it.
    lhat: Option<f32>,
    /// The product of 1 / [`Bsdf::radiance_scale`](crate::bsdf::Bsdf::radiance_scale) over the refractions so far: `beta` times
    /// this is the throughput without the eta^2 factors, which Russian roulette looks at.
    eta_scale: f32,
}

impl WalkState {
    /// A walk along `ray` in `medium` with throughput `beta`, after the scattering at `prev`.
    fn new(ray: Ray, medium: Option<u32>, beta: Rgb, prev: Previous) -> Self {
        WalkState {
            ray,
            medium,
            beta,
            depth: 0,
            rough: 0,
            prev,
            lead: 0.0,
            beta_start: beta.max_element(),
            lhat: None,
            eta_scale: 1.0,
        }
    }
}

/// The environment's radiance for a walk that escaped, MIS-weighted against light sampling.
fn escaped(scene: &Scene, selection: &LightSelection, w: &WalkState) -> Rgb {
    let Some(e) = scene.environment else {
        return Rgb::ZERO;
    };
    let crate::scene::Light::Environment(env) = &scene.lights[e as usize] else {
        return Rgb::ZERO;
    };
    let mis = if w.prev.singular {
        1.0
    } else {
        let pmf = selection.pmf(scene, w.prev.p, w.prev.n, e);
        power_heuristic(w.prev.pdf_dir, pmf * env.pdf(w.ray.d))
    };
    w.beta * env.radiance(w.ray.d) * mis
}

/// The area light `li`'s radiance found by chance at `hit`, MIS-weighted against light
/// sampling; `None` when `li` is not an area light (the walk ends).
fn emission_found(
    scene: &Scene,
    (selection, draw): (&LightSelection, LightPointDraw),
    w: &WalkState,
    hit: &crate::geometry::Hit,
    li: u32,
) -> Option<Rgb> {
    let light = &scene.lights[li as usize];
    if !matches!(light, crate::scene::Light::Area { .. }) {
        return None;
    }
    let radiance = light.area_radiance(&scene.prims, hit.prim, hit.p);
    let mis = if w.prev.singular {
        1.0
    } else {
        let at = (hit.p, hit.ng, hit.prim);
        let pdf_light = selection.pmf(scene, w.prev.p, w.prev.n, li)
            * scene.lights[li as usize].pdf_li(&scene.prims, w.prev.p, at, draw);
        power_heuristic(w.prev.pdf_dir, pdf_light)
    };
    Some(w.beta * radiance * mis)
}

/// The volume emittance L_e,V0 (eqs. 1 and 3) collected at the collision `p` in medium `m` that
/// `prop` sampled, MIS-weighted against [`volume_next_event`] when `nee` is on (weight 1 when
/// the walk alone collects the emission).
///
/// The collision estimator: along a free flight the in-scattered and emitted radiance of
/// eq. (3) is the integral of T(t) L_e,V0(t) dt; a collision drawn with density p(t) (the
/// product of the passage probabilities before it and its own collision density, Table 1, as
/// delta tracking draws it too) estimates it by T(t) L_e,V0(t) / p(t), unbiased wherever
/// p(t) > 0, which holds wherever sigma_t > 0 (an emitting medium must have some extinction).
/// The same collision then scatters with weight T sigma_s / p, so each collision adds the
/// emission once. The walk's density of `p` per unit volume is pdf_dir p(t) / r^2 (dV =
/// r^2 dw dr, eq. 5's volume vertex), the measure [`VolumeEmitters::pdf`] is in.
///
/// [`VolumeEmitters::pdf`]: crate::scene::emitters::VolumeEmitters::pdf
// ANCHOR: volume_emission_found
fn volume_emission_found(
    scene: &Scene,
    w: &WalkState,
    prop: &crate::scene::Propagation,
    (p, m): (Vec3, u32),
    nee: bool,
) -> Rgb {
    // ASSIGNMENT: volume_emission_found
    if prop.pdf <= 0.0 {
        return Rgb::ZERO;
    }
    let le = scene.media[m as usize].emission(p);
    let mis = if w.prev.singular || !nee {
        1.0
    } else {
        let r2 = (p - w.prev.p).length_squared();
        let pdf_walk = w.prev.pdf_dir * prop.pdf / r2;
        power_heuristic(pdf_walk, scene.emitters.pdf(m, p))
    };
    w.beta * prop.transmittance * le * (mis / prop.pdf)
    // END ASSIGNMENT
}
// ANCHOR_END: volume_emission_found

/// Next-event estimation toward the emitting media: a point x of them drawn by emitted power
/// (density pdf_V per unit volume, [`VolumeEmitters::sample`]), the light it sends to the
/// vertex `p` (normal `n` on a surface) through the transmittance T(p, x): the integrand of
/// eq. (5) with x0 = x a volume vertex, f T L_e,V0(x) / r^2 per unit volume, over pdf_V. The
/// power heuristic weighs it against the walk reaching x (`scatter`'s solid-angle density,
/// times the free-flight collision density at x, over r^2), the partner of
/// [`volume_emission_found`]. Draws no random number in a scene without emitting media.
///
/// [`VolumeEmitters::sample`]: crate::scene::emitters::VolumeEmitters::sample
// ANCHOR: volume_next_event
pub fn volume_next_event(
    scene: &Scene,
    (p, n): (Vec3, Option<Vec3>),
    medium: impl Fn(Vec3) -> Option<u32>,
    sampler: &mut Sampler,
    scatter: impl Fn(Vec3) -> (Rgb, f32),
) -> Rgb {
    if scene.emitters.is_empty() {
        return Rgb::ZERO;
    }
    let u_select = sampler.next_f32();
    let u = Vec3::new(sampler.next_f32(), sampler.next_f32(), sampler.next_f32());
    let Some(vs) = scene.emitters.sample(scene, u_select, u) else {
        return Rgb::ZERO;
    };
    let r2 = (vs.p - p).length_squared();
    if vs.emission == Rgb::ZERO || r2.is_nan() || r2 <= 0.0 {
        return Rgb::ZERO;
    }
    let wi = (vs.p - p) / r2.sqrt();
    let (f, pdf_scatter) = scatter(wi);
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    let origin = n.map_or(p, |n| offset_origin(p, n, wi));
    let lead = (origin - p).dot(wi);
    let Some((tr, pdf_ff)) =
        scene.volume_edge((origin, lead), vs.p, medium(wi), vs.medium, sampler)
    else {
        return Rgb::ZERO;
    };
    let mis = power_heuristic(vs.pdf, pdf_scatter * pdf_ff / r2);
    f * tr * vs.emission * (mis / (vs.pdf * r2))
}
// ANCHOR_END: volume_next_event

/// The direct image of every delta light (point, spot, directional) on the camera's film: one
/// splat per light the camera sees, with its transmittance from `sampler`; a thin lens spreads
/// it over the light's circle of confusion, one lens point per light and pass.
///
/// A path x_0 x_1 from a Dirac light to the pinhole has no vertex a walk from the camera can hit
/// (Pauly et al. 2000, eq. 5: both ends are Diracs), yet its measurement is finite: the light
/// images to a point of the film, all of its flux in one pixel. BDPT reaches it as strategy
/// (s, t) = (1, 1); the path tracer and SMC add it here, once per light and pass, so that every
/// integrator renders the same image (the flux of a point light in view is not lost).
// ANCHOR: delta_light_view
pub fn delta_light_view(scene: &Scene, sampler: &mut Sampler) -> Vec<(glam::Vec2, Rgb)> {
    let Some(cam) = scene.camera.as_ref() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    if scene.min_depth() > 0 {
        // every path of this image has no scattering vertex
        return out;
    }
    for light in scene.lights.iter().filter(|l| l.is_delta()) {
        // the lens point (drawn before the light's numbers; none for the pinhole)
        let lens = cam.sample_lens(sampler);
        let u = (sampler.next_2d(), 0.0);
        let Some(ls) = light.sample_li(&scene.prims, lens, u, LightPointDraw::Area) else {
            continue;
        };
        let Some(imp) = cam.importance(lens, ls.wi) else {
            continue;
        };
        if ls.value == Rgb::ZERO || ls.pdf <= 0.0 {
            continue;
        }
        let dist = if ls.dist.is_infinite() {
            f32::INFINITY
        } else {
            shadow_distance(lens, ls.p)
        };
        let tr = scene.transmittance(lens, ls.wi, dist, scene.camera_medium, sampler);
        // W_e times the lens's cosine over the lens point's density (1 for the pinhole: its
        // delta position absorbs the area measure)
        let cos = ls.wi.dot(cam.forward);
        let l = ls.value * tr * (imp.we * cos / ls.pdf) / cam.lens_pdf_area();
        if l != Rgb::ZERO && l.is_finite() {
            out.push((imp.raster, l));
        }
    }
    out
}
// ANCHOR_END: delta_light_view

/// Next-event estimation from `p` (surface normal `n` if on a surface), with MIS against the
/// scattering sampler: `scatter(wi)` returns (f * |cos| or f_p, solid-angle pdf of sampling wi
/// there), `medium(wi)` the medium the shadow ray starts in (a refracting surface such as rough
/// glass sees the medium behind it). Shared by the path tracer and SMC's surface vertices.
// ANCHOR: next_event
pub fn next_event(
    scene: &Scene,
    p: Vec3,
    n: Option<Vec3>,
    medium: impl Fn(Vec3) -> Option<u32>,
    sampler: &mut Sampler,
    scatter: impl Fn(Vec3) -> (Rgb, f32),
) -> Rgb {
    next_event_weighted(
        scene,
        (&LightSelection::Power, LightPointDraw::Area),
        p,
        n,
        medium,
        sampler,
        scatter,
        |_, _| 1.0,
    )
}

/// [`next_event`] with the estimate of light `l`'s sample `ls` multiplied by `weight(l, ls)`:
/// the distance-MIS weight of a free-flight vertex (`distance =
/// "equiangular-mis"`), which depends on the light point the sample drew.
#[allow(clippy::too_many_arguments)]
pub fn next_event_weighted(
    scene: &Scene,
    (selection, draw): (&LightSelection, LightPointDraw),
    p: Vec3,
    n: Option<Vec3>,
    medium: impl Fn(Vec3) -> Option<u32>,
    sampler: &mut Sampler,
    scatter: impl Fn(Vec3) -> (Rgb, f32),
    weight: impl Fn(usize, &crate::scene::light::LightSample) -> f32,
) -> Rgb {
    // ASSIGNMENT: next_event
    let Some((l, pmf, u_prim)) = selection.sample(scene, p, n, sampler.next_f32()) else {
        return Rgb::ZERO;
    };
    let light = &scene.lights[l];
    let u = sampler.next_2d();
    let Some(ls) = light.sample_li(&scene.prims, p, (u, u_prim), draw) else {
        return Rgb::ZERO;
    };
    let w = weight(l, &ls);
    if w == 0.0 {
        return Rgb::ZERO;
    }
    w * light_sample_estimate(scene, p, n, medium, sampler, scatter, &ls, pmf)
    // END ASSIGNMENT
}

/// The estimate of one light sample `ls` (from a light selected with probability `pmf`) at
/// `p`: the shadow ray's transmittance, the scattering, and the MIS weight against the
/// scattering sampler (see [`next_event`] for the arguments).
#[allow(clippy::too_many_arguments)]
pub fn light_sample_estimate(
    scene: &Scene,
    p: Vec3,
    n: Option<Vec3>,
    medium: impl Fn(Vec3) -> Option<u32>,
    sampler: &mut Sampler,
    scatter: impl Fn(Vec3) -> (Rgb, f32),
    ls: &crate::scene::light::LightSample,
    pmf: f32,
) -> Rgb {
    // ASSIGNMENT: next_event
    if ls.value == Rgb::ZERO || ls.pdf <= 0.0 {
        return Rgb::ZERO;
    }
    let (f, pdf_scatter) = scatter(ls.wi);
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    let origin = match n {
        Some(n) => offset_origin(p, n, ls.wi),
        None => p,
    };
    // aim from the lifted origin at the light point itself: along ls.wi (which leaves the
    // unlifted p) the ray would end behind the light's surface whenever both ends see each
    // other at grazing angles, and the light would occlude itself
    let (dir, dist) = if ls.dist.is_infinite() {
        (ls.wi, f32::INFINITY)
    } else {
        let dir = (ls.p - origin).normalize_or_zero();
        (dir, shadow_distance(origin, ls.p))
    };
    let tr = scene.transmittance(origin, dir, dist, medium(ls.wi), sampler);
    if tr == Rgb::ZERO {
        return Rgb::ZERO;
    }
    let pdf_light = pmf * ls.pdf;
    let w = if ls.is_delta {
        1.0
    } else {
        power_heuristic(pdf_light, pdf_scatter)
    };
    f * ls.value * tr * (w / pdf_light)
    // END ASSIGNMENT
}
// ANCHOR_END: next_event

/// The path tracer's facts: tile results only, no splats or records, split by passes.
pub struct PathFacts;

impl super::Facts for PathFacts {
    fn prepare<'t>(
        &self,
        setup: &super::Setup<'_, 't>,
    ) -> Result<Box<dyn super::Integrator + 't>, super::IntegratorError> {
        prepare(setup)
    }

    fn unreachable(&self) -> super::reach::Unreachable {
        super::reach::Unreachable::DiracLightsBehindSpecular
    }

    fn pass_footprint(&self, _: &super::Case) -> super::PassFootprint {
        super::PassFootprint {
            tiles: true,
            bytes_per_sample: 0,
        }
    }

    /// It collects emission along free flights and samples emitting media as lights.
    fn emitting_media_refusal(&self) -> Option<&'static str> {
        None
    }

    /// Equiangular sampling and the light selection are its next-event estimation's.
    fn takes(&self, option: super::OwnOption) -> bool {
        use super::OwnOption::*;
        matches!(
            option,
            EquiangularDistance | LightSelection | LightPoint | HaloCone | PixelSamples
        )
    }

    /// Its surface and medium vertices sample from the guide's mixtures (eq. 5.18 and its
    /// medium form); it starts no light paths, so the guide's emission (eq. 5.17) is unused.
    fn takes_guide(&self) -> bool {
        true
    }
}

/// The path tracer for the render loop: its depth limit, distance sampling, light selection
/// and the setup's technique where it guides scattering.
pub fn prepare<'t>(
    setup: &super::Setup<'_, 't>,
) -> Result<Box<dyn super::Integrator + 't>, super::IntegratorError> {
    let distance = setup.settings.distance;
    let selection = LightSelection::build(setup.settings.light_selection, setup.scene);
    if distance == DistanceSampling::EquiangularMis {
        check_equiangular(setup.scene)?;
        if setup.settings.given.light_point == Some(LightPointDraw::SolidAngleNear) {
            return Err(super::IntegratorError::Refused(
                "light_point = \"solid-angle-near\" (--light-point) cannot go with distance = \"equiangular-mis\": equiangular sampling draws its light point before the distance, by area, and the distance weights compare the two draws of that point".into(),
            ));
        }
    }
    let guided = setup.technique.guides_scattering();
    let halo_cone = if guided {
        0.0
    } else {
        setup.settings.halo_cone
    };
    if guided && setup.settings.given.halo_cone.is_some_and(|a| a > 0.0) {
        return Err(super::IntegratorError::Refused(
            "halo_cone (--halo-cone) cannot go with the guide: the guide draws the scattering directions from its own mixtures".into(),
        ));
    }
    Ok(Box::new(
        PathTracer::new(setup.max_depth)
            .with_distance(distance)
            .with_light_selection(selection)
            .with_light_point(setup.settings.light_point)
            .with_volume_next_event(setup.settings.volume_next_event)
            .with_guide(setup.technique)
            .with_halo_cone(setup.scene, halo_cone),
    ))
}

/// Equiangular sampling's MIS needs the density with which free flight draws any point of a
/// ray: Table 1's, which tracking follows and a march does not. Refused for a scene with a
/// marched medium (`propagation` other than `delta-tracking`), naming it.
pub fn check_equiangular(scene: &Scene) -> Result<(), super::IntegratorError> {
    for (m, name) in scene.media.iter().zip(&scene.medium_names) {
        if m.marched() {
            return Err(super::IntegratorError::Refused(format!(
                "distance = \"equiangular-mis\" (--distance) needs homogeneous or tracked media: medium `{name}` is marched (use propagation = \"delta-tracking\" or free-flight)"
            )));
        }
    }
    Ok(())
}

impl super::Integrator for PathTracer<'_> {
    fn label(&self) -> String {
        "path".into()
    }

    fn camera_sample(
        &self,
        scene: &Scene,
        cam: &crate::scene::Camera,
        raster: glam::Vec2,
        sampler: &mut Sampler,
        _scratch: &mut super::Scratch,
    ) -> Rgb {
        self.radiance(
            scene,
            cam.sample_ray(raster, sampler),
            scene.camera_medium,
            sampler,
        )
    }

    fn meter_sample(
        &self,
        scene: &Scene,
        meter: u32,
        sampler: &mut Sampler,
        _scratch: &mut super::Scratch,
    ) -> Rgb {
        self.meter_irradiance(scene, &scene.sensors[meter as usize], sampler)
    }

    fn delta_light_view(&self, scene: &Scene, sampler: &mut Sampler) -> Vec<super::Splat> {
        delta_light_view(scene, sampler)
    }
}
