//! The random walks of both subpaths: the eye subpath from the camera or a meter, the light
//! subpath from an emitted ray, each vertex recorded with its throughput and forward density
//! and its predecessor's reverse density, within the caller's [`WalkLimits`].

use glam::{Vec2, Vec3};

use super::MAX_SUBPATH_VERTICES;
use super::{volume_share, Bdpt, Scratch, SensorStart, Strategies, WalkLimits};
use crate::bsdf::{Lobe, TransportMode};
use crate::geometry::{offset_origin, Primitive, Ray};
use crate::math::{warp, Frame, Sampler};
use crate::path::geometry_term::cosine_factor;
use crate::path::geometry_term::to_area;
use crate::path::technique::{sample_emitted_start, EmittedStart, ScatterSample};
use crate::path::technique::{RR_MAX_SURVIVAL, RR_START_DEPTH};
use crate::path::{Vertex, VertexKind};
use crate::scene::light::EmissionSample;
use crate::scene::{Event, Light, Scene};
use crate::spectrum::Rgb;

/// How the first vertex after the origin was sampled.
#[derive(Clone, Copy)]
enum FirstPdf {
    /// A direction with this solid-angle density.
    SolidAngle(f32),
    /// A position on a disk perpendicular to the direction, with this area density (infinite
    /// lights): the next vertex's density is this times its cosine factor.
    Perpendicular(f32),
}

/// Where a random walk starts: its first ray and medium, the throughput so far, how its first
/// vertex's density is measured, the quantity it carries, how many vertices it may hold and
/// whether Russian roulette may end it.
struct WalkStart {
    ray: Ray,
    medium: Option<u32>,
    beta: Rgb,
    first: FirstPdf,
    mode: TransportMode,
    max_vertices: usize,
    roulette: bool,
}

/// A walk's state between vertices: the ray to propagate, the medium it starts in, the
/// throughput, whether its origin is a medium vertex and the lift of its origin.
struct Walk {
    ray: Ray,
    medium: Option<u32>,
    beta: Rgb,
    origin_in_medium: bool,
    lead: f32,
    /// The solid-angle density of the direction just sampled (0 before a perpendicular start).
    pdf_dir: f32,
    /// True until the first vertex after the origin is recorded.
    first_edge: bool,
    /// The throughput at the start, against which Russian roulette compares.
    beta_start: f32,
    /// The product of 1 / `Bsdf::radiance_scale` over the refractions of a radiance walk:
    /// roulette compares `beta` times this, without the eta^2 its exit from glass restores.
    eta_scale: f32,
    /// Vertices of the path after its origin that scattered from a lobe with a density:
    /// roulette starts once there are `RR_START_DEPTH` (Dirac lobes do not count).
    rough: u32,
}

impl Walk {
    /// The state of a walk from `start` continuing `path` (whose last vertex is its origin).
    fn new(start: &WalkStart, path: &[Vertex]) -> Self {
        let pdf_dir = match start.first {
            FirstPdf::SolidAngle(p) => p,
            FirstPdf::Perpendicular(_) => 0.0,
        };
        let beta_start = start.beta.max_element().max(f32::MIN_POSITIVE);
        let origin_in_medium = path.last().is_some_and(Vertex::is_medium);
        // distance between the last vertex and the lifted ray origin (see `Scene::propagate`)
        let lead = path
            .last()
            .map_or(0.0, |v| (start.ray.o - v.p).dot(start.ray.d).max(0.0));
        Walk {
            ray: start.ray,
            medium: start.medium,
            beta: start.beta,
            origin_in_medium,
            lead,
            pdf_dir,
            first_edge: true,
            beta_start,
            eta_scale: 1.0,
            rough: path.iter().skip(1).filter(|v| !v.delta).count() as u32,
        }
    }
}

/// The vertex of the environment light a `mode` walk escaping along `ray` reaches (eye walks
/// only; `None` without an environment).
fn environment_vertex(scene: &Scene, ray: &Ray, mode: TransportMode) -> Option<Vertex> {
    if mode != TransportMode::Radiance {
        return None;
    }
    let env = scene.environment?;
    Some(Vertex::new(
        VertexKind::InfiniteLight {
            light: env,
            w: ray.d,
        },
        ray.o + ray.d * (4.0 * scene.radius + (ray.o - scene.center).length()),
        Vec3::ZERO,
        None,
        None,
    ))
}

impl Bdpt<'_> {
    /// Vertices a walk may hold: the depth limit plus the `extra` vertices of its sensor or
    /// light (and its connection), within `limits`.
    fn max_vertices(&self, extra: u32, limits: WalkLimits) -> usize {
        (self.max_depth.saturating_add(extra) as usize)
            .min(MAX_SUBPATH_VERTICES)
            .min(limits.max_vertices)
    }

    /// The random walk shared by both subpaths: propagate, record the vertex with its forward
    /// density, scatter, and set the predecessor's reverse density.
    // ANCHOR: random_walk
    fn random_walk(
        &self,
        scene: &Scene,
        start: WalkStart,
        path: &mut Vec<Vertex>,
        sampler: &mut Sampler,
    ) {
        let mut w = Walk::new(&start, path);
        while path.len() < start.max_vertices {
            if Self::next_vertex(scene, &start, &mut w, path, sampler).is_none() {
                return;
            }
            if path.len() >= start.max_vertices {
                return;
            }
            if self
                .scatter_last(scene, &start, &mut w, path, sampler)
                .is_none()
            {
                return;
            }
        }
    }
    // ANCHOR_END: random_walk

    /// Propagates the walk `w` to its next vertex and records it on `path` with its throughput
    /// and forward density (Table 1's propagation pdf included); `None` ends the walk (an
    /// escape records the environment's vertex first).
    fn next_vertex(
        scene: &Scene,
        start: &WalkStart,
        w: &mut Walk,
        path: &mut Vec<Vertex>,
        sampler: &mut Sampler,
    ) -> Option<()> {
        let prev = path.len() - 1;
        // the camera's first ray sees through hidden emitters (`Scene::camera_bvh`)
        let from_camera = matches!(path[prev].kind, VertexKind::Camera);
        let ends = (w.origin_in_medium, from_camera);
        let prop = scene.propagate_bidirectional(w.ray, w.lead, w.medium, ends, sampler);
        // tau / p only: sigma_s belongs to f-hat of the medium vertex (eq. 6), applied when
        // the vertex scatters below and in every connection through it
        if prop.pdf <= 0.0 {
            return None;
        }
        w.beta *= prop.transmittance / prop.pdf;
        if w.beta == Rgb::ZERO {
            return None;
        }
        let mut v = match prop.event {
            Event::Escape => {
                if let Some(mut v) = environment_vertex(scene, &w.ray, start.mode) {
                    v.beta = w.beta;
                    v.pdf_fwd = w.pdf_dir * prop.pdf;
                    v.prop_fwd = prop.pdf;
                    v.prop_rev = prop.pdf_rev;
                    path.push(v);
                }
                return None;
            }
            Event::Medium { p, medium: m, .. } => Vertex::new(
                VertexKind::Medium { medium: m },
                p,
                Vec3::ZERO,
                Some(m),
                Some(m),
            ),
            Event::Surface { hit, medium: m } => Vertex::on_surface(scene, &hit, m),
        };
        v.beta = w.beta;
        let density = match (start.first, w.first_edge) {
            (FirstPdf::Perpendicular(p), true) => p * cosine_factor(&v, w.ray.d),
            _ => to_area(w.pdf_dir, &path[prev], &v),
        };
        v.pdf_fwd = density * prop.pdf;
        v.prop_fwd = prop.pdf;
        v.prop_rev = prop.pdf_rev;
        w.first_edge = false;
        path.push(v);
        Some(())
    }

    /// Scatters the walk `w` at the last vertex of `path`: the technique's direction, the
    /// vertex's lobe, the predecessor's reverse density and Russian roulette (when `start`
    /// allows it); `None` ends it.
    fn scatter_last(
        &self,
        scene: &Scene,
        start: &WalkStart,
        w: &mut Walk,
        path: &mut [Vertex],
        sampler: &mut Sampler,
    ) -> Option<()> {
        let (cur, mode) = (path.len() - 1, start.mode);
        let prev = cur - 1;
        let v = path[cur];
        let wo = -w.ray.d;
        // the BSDF or phase function, or the guided mixture (Kristensen 2010, eqs. 5.18,
        // 5.19 and their medium extension), with the density of the reverse walk
        let ss = self.tech.sample_scatter(scene, &v, wo, mode, sampler)?;
        if ss.pdf <= 0.0 {
            return None;
        }
        let reverse = match mode {
            TransportMode::Radiance => TransportMode::Importance,
            TransportMode::Importance => TransportMode::Radiance,
        };
        let (pdf_fwd_dir, pdf_rev_dir, lobe, delta) =
            self.scatter(scene, &v, &ss, wo, reverse, w)?;
        path[cur].lobe = lobe;
        if delta {
            path[cur].delta = true;
        } else {
            w.rough += 1;
        }
        w.pdf_dir = pdf_fwd_dir;
        // the predecessor as sampled from here (the reverse walk)
        path[prev].pdf_rev = to_area(pdf_rev_dir, &path[cur], &path[prev]) * path[cur].prop_rev;
        // Russian roulette on the scattering throughput (not on L_e / p of the origin, nor
        // on the eta^2 of refractions), from the third vertex with a density: a chain of
        // specular vertices spreads no light, so it does not bring the roulette closer
        if start.roulette && w.rough >= RR_START_DEPTH {
            let ratio = w.beta.max_element() * w.eta_scale / w.beta_start;
            let q = (self.tech)
                .roulette_survival(ss.lhat, ratio, RR_MAX_SURVIVAL)
                .unwrap_or(ratio.min(RR_MAX_SURVIVAL));
            if sampler.next_f32() >= q || q.is_nan() {
                return None;
            }
            w.beta /= q;
        }
        Some(())
    }

    /// One scattering step of a walk at vertex `v` with sample `ss`: the throughput, the next
    /// ray and its medium, and the direction densities forward and (for `reverse`) backward,
    /// with the lobe the vertex took and whether it is a Dirac one; `None` ends the walk.
    fn scatter(
        &self,
        scene: &Scene,
        v: &Vertex,
        ss: &ScatterSample,
        wo: Vec3,
        reverse: TransportMode,
        w: &mut Walk,
    ) -> Option<(f32, f32, Lobe, bool)> {
        Some(match v.kind {
            VertexKind::Medium { medium: m } => {
                w.beta *= scene.media[m as usize].sigma_s(v.p) * (ss.value / ss.pdf);
                w.medium = Some(m);
                w.origin_in_medium = true;
                w.ray = Ray::new(v.p, ss.wi);
                w.lead = 0.0;
                let rev = self.tech.scatter_pdf(scene, v, ss.wi, wo, reverse);
                (ss.pdf, rev, Lobe::Regular, false)
            }
            VertexKind::Surface { .. } => {
                let bs = ss.as_bsdf_sample();
                w.beta *= bs.weight(v.n);
                // a radiance walk crossing a refracting interface (importance has no eta^2)
                if reverse == TransportMode::Importance && bs.wi.dot(v.n) * wo.dot(v.n) < 0.0 {
                    if let Some(bsdf) = v.bsdf(scene) {
                        w.eta_scale /= bsdf.radiance_scale(wo, bs.wi, v.n);
                    }
                }
                w.medium = v.medium_towards(bs.wi);
                w.origin_in_medium = false;
                w.ray = Ray::new(offset_origin(v.p, v.n, bs.wi), bs.wi);
                w.lead = (w.ray.o - v.p).dot(bs.wi);
                if bs.lobe.is_singular() {
                    (0.0, 0.0, bs.lobe, true)
                } else {
                    let rev = self.tech.scatter_pdf(scene, v, bs.wi, wo, reverse);
                    (bs.pdf, rev, bs.lobe, false)
                }
            }
            _ => return None,
        })
    }

    /// One BDPT sample's two subpaths into `scratch`: the eye subpath from `start`, then a
    /// light subpath (Veach 1997 sec. 10.2), in this order of random numbers, both with BDPT's
    /// own [`WalkLimits::BDPT`]. The integrators, MLT's bootstrap and the adjoint image's
    /// pre-pass all draw their samples here, so their streams agree by construction; the
    /// strategies are then combined by the caller.
    pub fn sample(
        &self,
        scene: &Scene,
        start: SensorStart,
        sampler: &mut Sampler,
        scratch: &mut Scratch,
    ) {
        let limits = WalkLimits::BDPT;
        match start {
            SensorStart::Camera(raster) => {
                self.camera_subpath(scene, raster, limits, sampler, &mut scratch.eye)
            }
            SensorStart::Meter(m) => {
                self.meter_subpath(scene, m, limits, sampler, &mut scratch.eye)
            }
        }
        self.light_subpath(scene, limits, sampler, &mut scratch.light);
    }

    /// The eye subpath from the camera through raster position `raster`.
    pub fn camera_subpath(
        &self,
        scene: &Scene,
        raster: Vec2,
        limits: WalkLimits,
        sampler: &mut Sampler,
        path: &mut Vec<Vertex>,
    ) {
        path.clear();
        let Some(cam) = scene.camera.as_ref() else {
            return;
        };
        // a thin lens's point, uniform on the disk (the pinhole's eye, a Dirac)
        let lens = cam.sample_lens(sampler);
        let ray = cam.ray_through(raster, lens);
        let mut v0 = Vertex::new(
            VertexKind::Camera,
            lens,
            cam.forward,
            scene.camera_medium,
            scene.camera_medium,
        );
        v0.pdf_fwd = cam.lens_pdf_area();
        path.push(v0);
        let pdf_dir = cam.importance(lens, ray.d).map_or(0.0, |i| i.pdf_dir);
        // W_e cos / (per-pixel density p(lens) p(w)) = 1: the pixel is the mean over its film
        // area (and over the lens)
        let start = WalkStart {
            ray,
            medium: scene.camera_medium,
            beta: Rgb::ONE,
            first: FirstPdf::SolidAngle(pdf_dir),
            mode: TransportMode::Radiance,
            max_vertices: self.max_vertices(2, limits),
            roulette: limits.roulette,
        };
        self.random_walk(scene, start, path, sampler);
    }

    /// The eye subpath from a uniform point of meter `m`, cosine-distributed.
    pub fn meter_subpath(
        &self,
        scene: &Scene,
        m: u32,
        limits: WalkLimits,
        sampler: &mut Sampler,
        path: &mut Vec<Vertex>,
    ) {
        path.clear();
        let meter = &scene.sensors[m as usize];
        let q = Primitive::Quad(meter.quad);
        let (p, n) = q.sample_area(sampler.next_2d());
        let mut v0 = Vertex::new(
            VertexKind::Meter { meter: m },
            p,
            n,
            meter.medium,
            meter.medium,
        );
        v0.pdf_fwd = 1.0 / q.area();
        path.push(v0);
        if self.strategies == Strategies::LightTracing {
            // light tracing uses z_0 alone (t = 1): the walk would be traced for nothing
            return;
        }
        let local = warp::cosine_hemisphere(sampler.next_2d());
        if local.z <= 0.0 {
            return;
        }
        let wi = Frame::from_normal(n).to_world(local);
        let pdf = local.z * std::f32::consts::FRAC_1_PI;
        // W_e g / (p(x) p(w)) = (1/A) cos / ((1/A) cos/pi) = pi
        let start = WalkStart {
            ray: Ray::new(p, wi),
            medium: meter.medium,
            beta: Rgb::splat(std::f32::consts::PI),
            first: FirstPdf::SolidAngle(pdf),
            mode: TransportMode::Radiance,
            max_vertices: self.max_vertices(2, limits),
            roulette: limits.roulette,
        };
        self.random_walk(scene, start, path, sampler);
    }

    /// The light subpath: a light chosen by power, an emitted ray, then the random walk with the
    /// adjoint BSDF, from the medium around the light (`Scene::light_media`).
    pub fn light_subpath(
        &self,
        scene: &Scene,
        limits: WalkLimits,
        sampler: &mut Sampler,
        path: &mut Vec<Vertex>,
    ) {
        path.clear();
        let volume = volume_share(scene);
        // the choice between the lights and the emitting media draws a number only when
        // some medium glows
        if volume > 0.0 && (volume >= 1.0 || sampler.next_f32() < volume) {
            return self.volume_light_subpath(scene, volume, limits, sampler, path);
        }
        if scene.lights.is_empty() {
            return;
        }
        let Some(EmittedStart {
            light: l,
            pmf,
            es,
            start_pdf,
            prim: start_prim,
            ..
        }) = self.emitted_start(scene, sampler)
        else {
            return;
        };
        let light = &scene.lights[l];
        if es.pdf_pos <= 0.0 || es.pdf_dir <= 0.0 || es.value == Rgb::ZERO {
            return;
        }
        let lm = scene.light_medium(l, start_prim);
        let Some((mut v0, origin, first)) =
            light_start_vertex(light, l as u32, start_prim, &es, lm)
        else {
            return;
        };
        v0.beta = es.value;
        v0.pdf_fwd = v0.light_origin_pdf(scene, self.tech);
        if let VertexKind::InfiniteLight { .. } = v0.kind {
            v0.pdf_fwd = match light {
                Light::Environment(_) => pmf * es.pdf_dir * (1.0 - volume),
                _ => 0.0,
            };
        }
        let start_pdf = start_pdf * (1.0 - volume);
        let cos = if es.n == Vec3::ZERO || v0.is_infinite_light() {
            1.0
        } else {
            es.n.dot(es.d).abs()
        };
        let beta = es.value * (cos / (start_pdf * es.pdf_dir));
        path.push(v0);
        let start = WalkStart {
            ray: Ray::new(origin, es.d),
            medium: lm,
            beta,
            first,
            mode: TransportMode::Importance,
            max_vertices: self.max_vertices(1, limits),
            roulette: limits.roulette,
        };
        self.random_walk(scene, start, path, sampler);
    }

    /// The light subpath from a volume vertex x0 of the emitting media (eq. 5): a point by
    /// emitted power (`volume`: the media's share of the selection), a direction uniform on
    /// the sphere; x0's density is per unit volume, the first edge's per solid angle.
    fn volume_light_subpath(
        &self,
        scene: &Scene,
        volume: f32,
        limits: WalkLimits,
        sampler: &mut Sampler,
        path: &mut Vec<Vertex>,
    ) {
        let u_select = sampler.next_f32();
        let u = Vec3::new(sampler.next_f32(), sampler.next_f32(), sampler.next_f32());
        let u_dir = sampler.next_2d();
        let Some(vs) = scene.emitters.sample(scene, u_select, u) else {
            return;
        };
        // the lattice's cells may reach outside the medium
        if scene.medium_at(vs.p) != Some(vs.medium) || vs.emission == Rgb::ZERO {
            return;
        }
        let m = Some(vs.medium);
        let mut v0 = Vertex::new(
            VertexKind::Medium { medium: vs.medium },
            vs.p,
            Vec3::ZERO,
            m,
            m,
        );
        v0.pdf_fwd = v0.light_origin_pdf(scene, self.tech);
        if v0.pdf_fwd.is_nan() || v0.pdf_fwd <= 0.0 || volume <= 0.0 {
            return;
        }
        v0.beta = vs.emission;
        let pdf_dir = 0.25 * std::f32::consts::FRAC_1_PI;
        let d = warp::uniform_sphere(u_dir);
        let beta = vs.emission / (v0.pdf_fwd * pdf_dir);
        path.push(v0);
        let start = WalkStart {
            ray: Ray::new(vs.p, d),
            medium: m,
            beta,
            first: FirstPdf::SolidAngle(pdf_dir),
            mode: TransportMode::Importance,
            max_vertices: self.max_vertices(1, limits),
            roulette: limits.roulette,
        };
        self.random_walk(scene, start, path, sampler);
    }

    /// The light start: by power and area, or the technique's own (the adjoint image for area
    /// lights, Kristensen 2010, sec. 5.3.1; `start_pdf` is the position density with the
    /// selection), and the emission direction from c1 p_Le + c2 p_Wi (eq. 5.17) where the
    /// technique guides it; `None` when a sampler fails.
    fn emitted_start(&self, scene: &Scene, sampler: &mut Sampler) -> Option<EmittedStart> {
        let mut start = sample_emitted_start(self.tech, scene, sampler)?;
        let light = &scene.lights[start.light];
        if self.tech.guides_emission(light) {
            let es = &mut start.es;
            let n = es.n;
            let (d, pdf) =
                (self.tech).sample_emission(scene, light, (es.p, n), es.d, start.u_dir, sampler)?;
            let prim = start.prim.unwrap_or(0);
            es.value = crate::scene::light::emitted_by(light, &scene.prims, prim, (es.p, n), d);
            es.d = d;
            es.pdf_dir = pdf;
        }
        Some(start)
    }
}

/// The light subpath's first vertex for emitted ray `es` of light `l` (`prim`: the area
/// light's primitive, `lm`: the medium around the light), the origin of its first ray and how
/// its first edge's density is measured; `None` for an area light start without a primitive.
fn light_start_vertex(
    light: &Light,
    l: u32,
    start_prim: Option<u32>,
    es: &EmissionSample,
    lm: Option<u32>,
) -> Option<(Vertex, Vec3, FirstPdf)> {
    Some(match light {
        Light::Area { .. } => {
            let prim = start_prim?;
            let v = Vertex::new(
                VertexKind::Light {
                    light: l,
                    prim: Some(prim),
                },
                es.p,
                es.n,
                lm,
                lm,
            );
            (
                v,
                offset_origin(es.p, es.n, es.d),
                FirstPdf::SolidAngle(es.pdf_dir),
            )
        }
        Light::Point { .. } | Light::Spot { .. } => (
            Vertex::new(
                VertexKind::Light {
                    light: l,
                    prim: None,
                },
                es.p,
                Vec3::ZERO,
                lm,
                lm,
            ),
            es.p,
            FirstPdf::SolidAngle(es.pdf_dir),
        ),
        Light::Directional { .. } | Light::Environment(_) => (
            Vertex::new(
                VertexKind::InfiniteLight { light: l, w: -es.d },
                es.p,
                Vec3::ZERO,
                None,
                None,
            ),
            es.p,
            FirstPdf::Perpendicular(es.pdf_pos),
        ),
    })
}
