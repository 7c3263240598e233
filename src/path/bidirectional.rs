//! Bidirectional path tracing with multiple importance sampling, with media (Lafortune and
//! Willems 1996; Veach 1997 ch. 10; in the path-integral framework of Pauly, Kollig, Keller
//! 2000, eq. 7).
//!
//! A light subpath y_0 ... y_{s-1} and an eye subpath z_{t-1} ... z_0 (z_0 on the sensor) are
//! joined by one edge into a path of s + t vertices. Every (s, t) gives an unbiased estimate
//! f_j / (p(y) p(z)); the power heuristic weights them with the densities every other split of
//! the same path would have had. All densities are in the vertices' own measures (area on
//! surfaces, volume in the medium) and include the propagation pdfs of Table 1, so the weights
//! see medium vertices exactly as the path integral does.
//!
//! The walks and the single bidirectional sample live here, in the path layer, because the
//! enlightened preprocessing (the adjoint image's pre-pass, the particle samplers) traces them
//! too; `integrator::bdpt` combines the strategies of a sample into the film.
//! Book: "Bidirectional path tracing".

use glam::{Vec2, Vec3};

use crate::bsdf::{Lobe, TransportMode};
use crate::geometry::{offset_origin, Primitive, Ray};
use crate::math::{warp, Frame, Sampler};
use crate::path::geometry_term::cosine_factor;
use crate::path::subpath::{remap, Subpath, VertexCache};
use crate::path::technique::{sample_emitted_start, EmittedStart, ScatterSample, StartDraw};
use crate::path::vertex::to_area;
use crate::path::LocalSampling;
use crate::path::{Vertex, VertexKind};
use crate::scene::light::EmissionSample;
use crate::scene::{Event, Light, Scene};
use crate::spectrum::Rgb;
use TransportMode::Radiance;

use super::technique::{RR_MAX_SURVIVAL, RR_START_DEPTH};

/// Vertices per subpath at most, whatever Russian roulette decides (a safety net only).
pub const MAX_SUBPATH_VERTICES: usize = 256;

/// Which strategies are used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategies {
    /// All (s, t), weighted by the power heuristic.
    All,
    /// Light tracing: only t = 1 (light subpaths connected to the sensor), unweighted.
    LightTracing,
    /// One strategy alone, unweighted: an unbiased estimator of the paths it can sample (the
    /// debugging view, and the test that each strategy is unbiased on its own).
    Only(usize, usize),
}

/// How the first vertex after the origin was sampled.
#[derive(Clone, Copy)]
enum FirstPdf {
    /// A direction with this solid-angle density.
    SolidAngle(f32),
    /// A position on a disk perpendicular to the direction, with this area density (infinite
    /// lights): the next vertex's density is this times its cosine factor.
    Perpendicular(f32),
}

/// One strategy's unweighted contribution, the propagation pdfs of its connection edge (both
/// directions), the endpoint it sampled and the raster position it lands on.
struct Connection {
    l: Rgb,
    pdf_qp: f32,
    pdf_pq: f32,
    sampled: Option<Vertex>,
    raster: Option<Vec2>,
    /// The reverse densities the connection changes, when it computed them on the way.
    changed: Option<Changed>,
}

/// Strategy (s, t) of one joined path, for its MIS weight: the endpoint sampled for the
/// connection (s = 1 or t = 1), if any, and the connection edge's propagation pdfs (Table 1)
/// from the light side (`pdf_qp`) and from the eye side (`pdf_pq`), which every other split of
/// the path needs for its density (Veach 1997, sec. 10.2).
#[derive(Clone, Copy, Debug)]
pub struct Join {
    pub s: usize,
    pub t: usize,
    pub sampled: Option<Vertex>,
    pub pdf_qp: f32,
    pub pdf_pq: f32,
}

/// Where a random walk starts: its first ray and medium, the throughput so far, how its first
/// vertex's density is measured, the quantity it carries and how many vertices it may hold.
struct WalkStart {
    ray: Ray,
    medium: Option<u32>,
    beta: Rgb,
    first: FirstPdf,
    mode: TransportMode,
    max_vertices: usize,
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

/// Where a BDPT sample's eye subpath starts: the pinhole through a raster position, or a
/// point on an irradiance meter (the two sensors of the path integral's measurement, eq. 5).
#[derive(Clone, Copy, Debug)]
pub enum SensorStart {
    Camera(Vec2),
    Meter(u32),
}

/// Reusable per-thread storage, so no sample allocates.
#[derive(Default)]
pub struct Scratch {
    pub light: Vec<Vertex>,
    pub eye: Vec<Vertex>,
    /// The per-vertex values of both subpaths that `Bdpt::combine` computes once per sample.
    pub light_cache: Vec<VertexCache>,
    pub eye_cache: Vec<VertexCache>,
}

/// The reverse densities (in their vertices' measures, propagation included) that a
/// connection (s, t) gives the vertices next to it: p_{t-1}, p_{t-2} as sampled from the light
/// side and q_{s-1}, q_{s-2} as sampled from the eye side (Veach 1997, sec. 10.2); those of
/// vertices the path does not have are unused.
#[derive(Clone, Copy, Debug, Default)]
struct Changed {
    pt: f32,
    pt_minus: f32,
    qs: f32,
    qs_minus: f32,
}

/// The eye side's end p of a connection from a light walk's vertex q: the solid-angle
/// density with which p samples the direction to q, and, when p has a predecessor, the one
/// with which it samples the predecessor given q, with the conversion to its measure.
struct End<'a> {
    p: &'a Vertex,
    p_to_q: f32,
    p_minus: Option<(f32, crate::path::vertex::AreaFactor)>,
}

#[derive(Clone, Debug)]
pub struct Bdpt<'t> {
    /// The local-sampling technique of both walks, their MIS densities and light starts.
    pub tech: &'t dyn LocalSampling,
    pub max_depth: u32,
    pub strategies: Strategies,
    /// Medium around each light (for the first edge of light subpaths).
    light_media: Vec<Option<u32>>,
    /// Russian roulette in the walks (on by default; samplers that fix the walk lengths
    /// themselves, such as the bidirectional particle sampler, switch it off).
    pub roulette: bool,
    /// Vertices per subpath at most, below [`MAX_SUBPATH_VERTICES`] (a walk of exactly n
    /// vertices for the bidirectional particle sampler).
    pub vertex_cap: usize,
}

impl<'t> Bdpt<'t> {
    /// BDPT on `scene` sampling with technique `tech`.
    pub fn new(
        scene: &Scene,
        tech: &'t dyn LocalSampling,
        max_depth: Option<u32>,
        strategies: Strategies,
    ) -> Self {
        let light_media = scene
            .lights
            .iter()
            .map(|l| match l {
                Light::Area { prims, .. } => {
                    let (p, n) = scene.prims[prims[0] as usize].sample_area(Vec2::splat(0.5));
                    scene.medium_at(offset_origin(p, n, n))
                }
                Light::Point { position, .. } | Light::Spot { position, .. } => {
                    scene.medium_at(*position)
                }
                _ => None,
            })
            .collect();
        Bdpt {
            tech,
            max_depth: max_depth.unwrap_or(u32::MAX),
            strategies,
            light_media,
            roulette: true,
            vertex_cap: MAX_SUBPATH_VERTICES,
        }
    }

    /// The medium around light `l` (where its light subpaths start).
    pub fn light_medium(&self, l: usize) -> Option<u32> {
        self.light_media.get(l).copied().flatten()
    }

    /// The media around every light.
    pub fn light_media(&self) -> &[Option<u32>] {
        &self.light_media
    }

    fn max_vertices(&self, extra: u32) -> usize {
        (self.max_depth.saturating_add(extra) as usize)
            .min(MAX_SUBPATH_VERTICES)
            .min(self.vertex_cap)
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
                .scatter_last(scene, start.mode, &mut w, path, sampler)
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
        let prop =
            scene.propagate_bidirectional(w.ray, w.lead, w.medium, w.origin_in_medium, sampler);
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
        v.prop_rev = prop.pdf_rev;
        w.first_edge = false;
        path.push(v);
        Some(())
    }

    /// Scatters the walk `w` at the last vertex of `path`: the technique's direction, the
    /// vertex's lobe, the predecessor's reverse density and Russian roulette; `None` ends it.
    fn scatter_last(
        &self,
        scene: &Scene,
        mode: TransportMode,
        w: &mut Walk,
        path: &mut [Vertex],
        sampler: &mut Sampler,
    ) -> Option<()> {
        let cur = path.len() - 1;
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
        }
        w.pdf_dir = pdf_fwd_dir;
        // the predecessor as sampled from here (the reverse walk)
        path[prev].pdf_rev = to_area(pdf_rev_dir, &path[cur], &path[prev]) * path[cur].prop_rev;
        // Russian roulette on the scattering throughput (not on L_e / p of the origin)
        if self.roulette && cur as u32 >= RR_START_DEPTH {
            let ratio = w.beta.max_element() / w.beta_start;
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
    /// light subpath (Veach 1997 sec. 10.2), in this order of random numbers. The integrators,
    /// MLT's bootstrap and the adjoint image's pre-pass all draw their samples here, so their
    /// streams agree by construction; the strategies are then combined by the caller.
    pub fn sample(
        &self,
        scene: &Scene,
        start: SensorStart,
        sampler: &mut Sampler,
        scratch: &mut Scratch,
    ) {
        match start {
            SensorStart::Camera(raster) => {
                self.camera_subpath(scene, raster, sampler, &mut scratch.eye)
            }
            SensorStart::Meter(m) => self.meter_subpath(scene, m, sampler, &mut scratch.eye),
        }
        self.light_subpath(scene, sampler, &mut scratch.light);
    }

    /// The eye subpath from the camera through raster position `raster`.
    pub fn camera_subpath(
        &self,
        scene: &Scene,
        raster: Vec2,
        sampler: &mut Sampler,
        path: &mut Vec<Vertex>,
    ) {
        path.clear();
        let Some(cam) = scene.camera.as_ref() else {
            return;
        };
        let ray = cam.generate_ray(raster);
        let mut v0 = Vertex::new(
            VertexKind::Camera,
            cam.eye,
            cam.forward,
            scene.camera_medium,
            scene.camera_medium,
        );
        v0.pdf_fwd = 1.0;
        path.push(v0);
        let pdf_dir = cam.importance(ray.d).map_or(0.0, |i| i.pdf_dir);
        // W_e cos / (per-pixel density) = 1: the pixel is the mean over its film area
        let start = WalkStart {
            ray,
            medium: scene.camera_medium,
            beta: Rgb::ONE,
            first: FirstPdf::SolidAngle(pdf_dir),
            mode: TransportMode::Radiance,
            max_vertices: self.max_vertices(2),
        };
        self.random_walk(scene, start, path, sampler);
    }

    /// The eye subpath from a uniform point of meter `m`, cosine-distributed.
    pub fn meter_subpath(
        &self,
        scene: &Scene,
        m: u32,
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
            max_vertices: self.max_vertices(2),
        };
        self.random_walk(scene, start, path, sampler);
    }

    /// The light subpath: a light chosen by power, an emitted ray, then the random walk with the
    /// adjoint BSDF.
    pub fn light_subpath(&self, scene: &Scene, sampler: &mut Sampler, path: &mut Vec<Vertex>) {
        path.clear();
        if scene.lights.is_empty() {
            return;
        }
        // the light start: by power and area, or the technique's own (the adjoint image for
        // area lights, Kristensen 2010, sec. 5.3.1); `start_pdf` is the position density with
        // the selection
        let Some(EmittedStart {
            light: l,
            pmf,
            mut es,
            start_pdf,
            prim: start_prim,
            u_dir,
        }) = sample_emitted_start(self.tech, scene, sampler)
        else {
            return;
        };
        let light = &scene.lights[l];
        // eq. (5.17): the emission direction from c1 p_Le + c2 p_Wi where guiding is on
        if self.tech.guides_emission(light) {
            let n = es.n;
            let Some((d, pdf)) =
                (self.tech).sample_emission(scene, light, (es.p, n), es.d, u_dir, sampler)
            else {
                return;
            };
            es.value = crate::scene::light::emitted_by(light, n, d);
            es.d = d;
            es.pdf_dir = pdf;
        }
        if es.pdf_pos <= 0.0 || es.pdf_dir <= 0.0 || es.value == Rgb::ZERO {
            return;
        }
        let lm = self.light_media[l];
        let Some((mut v0, origin, first)) =
            light_start_vertex(light, l as u32, start_prim, &es, lm)
        else {
            return;
        };
        v0.beta = es.value;
        v0.pdf_fwd = v0.light_origin_pdf(scene, self.tech);
        if let VertexKind::InfiniteLight { .. } = v0.kind {
            v0.pdf_fwd = match light {
                Light::Environment(_) => pmf * es.pdf_dir,
                _ => 0.0,
            };
        }
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
            max_vertices: self.max_vertices(1),
        };
        self.random_walk(scene, start, path, sampler);
    }

    /// The largest s to try with a light subpath `light`: its length, but at least 1 when the
    /// scene has lights, because s = 1 samples its own light vertex (next-event estimation)
    /// whatever became of the light subpath: a walk that ended before its first vertex (a
    /// guided emission direction behind the light) must not take that strategy with it.
    pub fn max_light_vertices(scene: &Scene, light: &[Vertex]) -> usize {
        if scene.lights.is_empty() {
            0
        } else {
            light.len().max(1)
        }
    }

    /// Whether light `l` is a Dirac in position or direction (it cannot be hit by chance).
    fn is_delta_light(scene: &Scene, v: &Vertex) -> bool {
        match v.kind {
            VertexKind::Light { light, .. } | VertexKind::InfiniteLight { light, .. } => {
                scene.lights[light as usize].is_delta()
            }
            _ => false,
        }
    }

    /// The power-heuristic weight of strategy (s, t) for the path joined from `light[..s]` and
    /// `eye[..t]`, with `sampled` replacing the endpoint that was sampled for the connection
    /// (s = 1 or t = 1). `conn` holds the connection edge's propagation pdfs.
    // ANCHOR: mis_weight
    pub fn mis_weight(&self, scene: &Scene, light: &[Vertex], eye: &[Vertex], join: Join) -> f32 {
        let changed = self.changed_densities(scene, light, eye, &join);
        self.weight(scene, light, eye, &join, changed)
    }

    /// The four reverse densities the connection `join` changes, from the vertices alone.
    fn changed_densities(
        &self,
        scene: &Scene,
        light: &[Vertex],
        eye: &[Vertex],
        join: &Join,
    ) -> Changed {
        use TransportMode::{Importance, Radiance};
        let (s, t) = (join.s, join.t);
        // the connection's ends as the joined path has them
        let qs = if s == 0 {
            None
        } else if s == 1 {
            Some(join.sampled.as_ref().unwrap_or_else(|| &light[0]))
        } else {
            Some(&light[s - 1])
        };
        let pt = if t == 1 && s != 1 {
            join.sampled.as_ref().unwrap_or_else(|| &eye[0])
        } else {
            &eye[t - 1]
        };
        let qs_minus = (s > 1).then(|| &light[s - 2]);
        let pt_minus = (t > 1).then(|| &eye[t - 2]);
        // pt as sampled from the light side
        let mut c = Changed {
            pt: 0.0,
            pt_minus: 0.0,
            qs: 0.0,
            qs_minus: 0.0,
        };
        c.pt = match qs {
            Some(q) => {
                q.pdf_area(scene, self.tech, qs_minus.map(|v| v.p), pt, Importance) * join.pdf_qp
            }
            None => pt.light_origin_pdf(scene, self.tech),
        };
        if let Some(pm) = pt_minus {
            c.pt_minus = match qs {
                Some(q) => pt.pdf_area(scene, self.tech, Some(q.p), pm, Importance),
                None => pt.light_pdf_to(scene, self.tech, pm),
            } * pt.prop_rev;
        }
        if let Some(q) = qs {
            c.qs = pt.pdf_area(scene, self.tech, pt_minus.map(|v| v.p), q, Radiance) * join.pdf_pq;
            if let Some(qm) = qs_minus {
                c.qs_minus = q.pdf_area(scene, self.tech, Some(pt.p), qm, Radiance) * q.prop_rev;
            }
        }
        c
    }

    /// The weight 1 / (1 + sum of r_i^2) of strategy `join` with the reverse densities
    /// `changed` of the four vertices next to the connection; every other vertex brings its
    /// subpath's own ratio (`Subpath::ratio`).
    fn weight<L: Subpath + ?Sized, E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light: &L,
        eye: &E,
        join: &Join,
        changed: Changed,
    ) -> f32 {
        let (s, t) = (join.s, join.t);
        let (lv, ev) = (light.vertices(), eye.vertices());
        // the connection's ends are connectible: their deltas count as false
        let pt_fwd = if t == 1 && s != 1 {
            join.sampled.as_ref().unwrap_or_else(|| &ev[0]).pdf_fwd
        } else {
            ev[t - 1].pdf_fwd
        };
        let mut sum = 0.0f32;
        let mut ri = 1.0f32;
        for i in (1..t).rev() {
            ri *= if i + 1 == t {
                remap(changed.pt) / remap(pt_fwd)
            } else if i + 2 == t {
                remap(changed.pt_minus) / remap(ev[i].pdf_fwd)
            } else {
                eye.ratio(i)
            };
            let delta = i + 1 != t && ev[i].delta;
            if !delta && !ev[i - 1].delta {
                sum += ri * ri;
            }
        }
        if s == 0 {
            return 1.0 / (1.0 + sum);
        }
        let qs = if s == 1 {
            join.sampled.as_ref().unwrap_or_else(|| &lv[0])
        } else {
            &lv[s - 1]
        };
        ri = 1.0;
        for i in (0..s).rev() {
            ri *= if i + 1 == s {
                remap(changed.qs) / remap(qs.pdf_fwd)
            } else if i + 2 == s {
                remap(changed.qs_minus) / remap(lv[i].pdf_fwd)
            } else {
                light.ratio(i)
            };
            let delta = i + 1 != s && lv[i].delta;
            let delta_before = if i > 0 {
                lv[i - 1].delta
            } else {
                // vertex 0 is the connection's end itself when s = 1
                Self::is_delta_light(scene, if s == 1 { qs } else { &lv[0] })
            };
            if !delta && !delta_before {
                sum += ri * ri;
            }
        }
        1.0 / (1.0 + sum)
    }

    /// [`Bdpt::changed_densities`] of a connection from the light walk's vertex q =
    /// `light[s - 1]` (s >= 2) to the end `ends.p` of the eye side, from the connection's
    /// vector `d` = p - q and its unit direction `w`, with q's per-vertex values and p's
    /// densities given: the same operands the vertices would give, so the same bits.
    fn changed_at_walk<L: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light: &L,
        s: usize,
        ends: End,
        (d, w): (Vec3, Vec3),
        (pdf_qp, pdf_pq): (f32, f32),
    ) -> Changed {
        use TransportMode::{Importance, Radiance};
        let (q, p) = (&light.vertices()[s - 1], ends.p);
        let wq = light.to_prev(s - 1);
        let d2 = d.length_squared();
        // `to_area` between p and q in either direction: the cosine at the far end over d^2
        // (the reversed vector is -d exactly, and g takes the cosine's absolute value)
        let area = |far: &Vertex, pdf: f32| {
            if d2 == 0.0 {
                0.0
            } else {
                pdf * cosine_factor(far, d / d2.sqrt()) / d2
            }
        };
        let tech = self.tech;
        Changed {
            pt: area(p, tech.scatter_pdf(scene, q, wq, w, Importance)) * pdf_qp,
            pt_minus: ends
                .p_minus
                .map_or(0.0, |(pdf, a)| a.apply(pdf) * p.prop_rev),
            qs: area(q, ends.p_to_q) * pdf_pq,
            qs_minus: light
                .prev_area(s - 1)
                .apply(tech.scatter_pdf(scene, q, w, wq, Radiance))
                * q.prop_rev,
        }
    }
    // ANCHOR_END: mis_weight

    /// The contribution of strategy (s, t), already MIS-weighted (unweighted for light
    /// tracing), with the raster position when it lands elsewhere than the sample's pixel.
    // ANCHOR: connect
    pub fn connect(
        &self,
        scene: &Scene,
        light: &[Vertex],
        eye: &[Vertex],
        s: usize,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<(Rgb, Option<Vec2>)> {
        self.connect_sampled(scene, light, eye, s, t, sampler)
            .map(|(l, raster, _)| (l, raster))
    }

    /// Every strategy (s, t) of one pair of subpaths within the depth limit, in the order
    /// `combine` uses, connected with [`Bdpt::connect_sampled`]: `visit(s, t, contribution,
    /// splat, sampled endpoint)` sees each non-zero one and returns false to stop. The pre-passes
    /// of MLT and of the adjoint image walk the strategies this way.
    pub fn for_each_strategy(
        &self,
        scene: &Scene,
        light: &[Vertex],
        eye: &[Vertex],
        sampler: &mut Sampler,
        visit: &mut dyn FnMut(usize, usize, Rgb, Option<Vec2>, Option<Vertex>) -> bool,
    ) {
        for t in 1..=eye.len() {
            for s in 0..=Self::max_light_vertices(scene, light) {
                let depth = s as i64 + t as i64 - 2;
                if depth < 0 || depth as u64 > self.max_depth as u64 {
                    continue;
                }
                let Some((l, splat, sampled)) =
                    self.connect_sampled(scene, light, eye, s, t, sampler)
                else {
                    continue;
                };
                if !visit(s, t, l, splat, sampled) {
                    return;
                }
            }
        }
    }

    /// [`Bdpt::connect`] that also returns the endpoint it sampled for s = 1 (a light vertex)
    /// or t = 1 (the sensor vertex), so the joined path can be rebuilt (MLT's initialization).
    pub fn connect_sampled(
        &self,
        scene: &Scene,
        light: &[Vertex],
        eye: &[Vertex],
        s: usize,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<(Rgb, Option<Vec2>, Option<Vertex>)> {
        self.connect_in(scene, light, eye, s, t, sampler)
    }

    /// [`Bdpt::connect_sampled`] on subpaths whose per-vertex values are given
    /// ([`crate::path::subpath::Cached`], `Bdpt::combine`) or computed on the fly (`[Vertex]`).
    pub fn connect_in<L: Subpath + ?Sized, E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light_path: &L,
        eye_path: &E,
        s: usize,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<(Rgb, Option<Vec2>, Option<Vertex>)> {
        let (light, eye) = (light_path.vertices(), eye_path.vertices());
        if t > 1 && s != 0 && eye[t - 1].is_infinite_light() {
            return None;
        }
        let mut sampled: Option<Vertex> = None;
        let mut raster = None;
        let mut changed = None;
        let (mut l, pdf_qp, pdf_pq);
        if s == 0 {
            // the eye subpath found an emitter by itself
            let pt = &eye[t - 1];
            let towards = eye[t - 2].p;
            l = match pt.kind {
                VertexKind::InfiniteLight { .. } => pt.emitted(scene, towards),
                _ => pt.surface_emission(scene, towards),
            } * pt.beta;
            pdf_qp = 1.0;
            pdf_pq = 1.0;
        } else if s == 1 {
            // next-event estimation: sample a point on a light for the eye subpath's end
            let c = self.connect_light_sample(scene, eye_path, t, sampler)?;
            (l, pdf_qp, pdf_pq, sampled, raster) = (c.l, c.pdf_qp, c.pdf_pq, c.sampled, c.raster);
            changed = c.changed;
        } else if t == 1
            && self.strategies == Strategies::LightTracing
            && matches!(eye[0].kind, VertexKind::Meter { .. })
        {
            // light tracing to a meter: two direction samplers combined by MIS
            if !light[s - 1].is_connectible(scene) || s < 2 {
                return None;
            }
            let (c, z0) = self.light_tracing_meter(scene, light, s, &eye[0], sampler)?;
            l = c;
            pdf_qp = 1.0;
            pdf_pq = 1.0;
            sampled = Some(z0);
        } else if t == 1 {
            // connect the light subpath to the sensor
            let c = self.connect_to_sensor(scene, light_path, eye, s, sampler)?;
            (l, pdf_qp, pdf_pq, sampled, raster) = (c.l, c.pdf_qp, c.pdf_pq, c.sampled, c.raster);
            changed = c.changed;
        } else {
            let c = self.connect_walks(scene, light_path, eye_path, s, t, sampler)?;
            (l, pdf_qp, pdf_pq) = (c.0, c.1, c.2);
            changed = c.3;
        }
        if l == Rgb::ZERO || !l.is_finite() {
            return if l.is_finite() {
                None
            } else {
                Some((l, raster, sampled))
            };
        }
        if self.strategies == Strategies::All {
            let join = Join {
                s,
                t,
                sampled,
                pdf_qp,
                pdf_pq,
            };
            let changed =
                changed.unwrap_or_else(|| self.changed_densities(scene, light, eye, &join));
            l *= self.weight(scene, light_path, eye_path, &join, changed);
        }
        Some((l, raster, sampled))
    }

    /// Strategy (s, t) with s, t >= 2: the light subpath's end q joined to the eye subpath's
    /// end p. Returns the unweighted contribution, the edge's propagation pdfs both ways and,
    /// when every strategy is weighted, the reverse densities the connection changes, all from
    /// one direction q -> p (its reverse is the same vector negated, exactly).
    #[allow(clippy::type_complexity)]
    fn connect_walks<L: Subpath + ?Sized, E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light: &L,
        eye: &E,
        s: usize,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<(Rgb, f32, f32, Option<Changed>)> {
        let qs = &light.vertices()[s - 1];
        let pt = &eye.vertices()[t - 1];
        if !qs.is_connectible(scene) || !pt.is_connectible(scene) {
            return None;
        }
        let d = pt.p - qs.p;
        let w = d.normalize_or_zero();
        // `f_hat(q_{s-2} -> q -> p)` and `f_hat(q -> p -> p_{t-2})`; a zero `d` (w zero
        // either way) is refused by the edge below
        let fq = qs.f_hat_dirs(scene, light.to_prev(s - 1), w);
        let fp = pt.f_hat_dirs(scene, -w, eye.to_prev(t - 1));
        if fq == Rgb::ZERO || fp == Rgb::ZERO {
            return None;
        }
        let e = scene.edge(qs.edge_end(pt.p), pt.edge_end(qs.p), sampler);
        if e.transmittance == Rgb::ZERO {
            return None;
        }
        // `geometry_term_unoccluded(qs, pt)` from the connection's vector
        let d2 = d.length_squared();
        let g = if d2 == 0.0 {
            0.0
        } else {
            let u = d / d2.sqrt();
            cosine_factor(qs, u) * cosine_factor(pt, u) / d2
        };
        let l = qs.beta * fq * e.transmittance * g * fp * pt.beta;
        let changed = (self.strategies == Strategies::All).then(|| {
            use TransportMode::{Importance, Radiance};
            let wp = eye.to_prev(t - 1);
            let ends = End {
                p: pt,
                p_to_q: self.tech.scatter_pdf(scene, pt, wp, -w, Radiance),
                p_minus: Some((
                    self.tech.scatter_pdf(scene, pt, -w, wp, Importance),
                    eye.prev_area(t - 1),
                )),
            };
            self.changed_at_walk(scene, light, s, ends, (d, w), (e.pdf_ab, e.pdf_ba))
        });
        Some((l, e.pdf_ab, e.pdf_ba, changed))
    }
    // ANCHOR_END: connect

    /// Strategy s = 1 (next-event estimation): a light vertex sampled for the eye subpath's
    /// end `eye[t - 1]`, by the technique's light start or by power, and its connection.
    fn connect_light_sample<E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        eye_path: &E,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<Connection> {
        let eye = eye_path.vertices();
        let mut raster = None;
        let pt = &eye[t - 1];
        if !pt.is_connectible(scene) {
            return None;
        }
        let (mut li, pmf, u_prim) = scene.light_distr.sample(sampler.next_f32());
        let u = sampler.next_2d();
        // `sel_pdf`: the solid-angle density with the light selection included
        let (ls, sel_pdf, start_prim) = match self.tech.sample_light_start(scene, li, u, sampler) {
            StartDraw::Failed => return None,
            StartDraw::Drawn(st) => {
                // the light vertex from the technique, as light subpaths start
                li = st.point.light as usize;
                let ls = scene.lights[li].li_from(pt.p, st.point.p, st.point.n, st.pdf)?;
                (ls, ls.pdf, Some(st.point.prim))
            }
            StartDraw::ByPower => {
                let light = &scene.lights[li];
                let ls = light.sample_li(&scene.prims, pt.p, u, u_prim)?;
                let prim = match light {
                    Light::Area { prims, distr, .. } => Some(prims[distr.sample(u_prim).0]),
                    _ => None,
                };
                (ls, pmf * ls.pdf, prim)
            }
        };
        if ls.pdf <= 0.0 || ls.value == Rgb::ZERO {
            return None;
        }
        let mut v = self.light_sample_vertex(scene, li, &ls, start_prim, pt.p);
        v.beta = ls.value / sel_pdf;
        let f = if t == 1 {
            // the sensor itself: W_e over the density of its point (1 for the pinhole, whose
            // W_e lands in another pixel, A * (1/A) for a meter)
            match pt.kind {
                VertexKind::Camera => {
                    let imp = scene.camera.as_ref()?.importance(ls.wi)?;
                    raster = Some(imp.raster);
                    Rgb::splat(imp.we)
                }
                VertexKind::Meter { .. } => pt.importance(scene, pt.p + ls.wi) / pt.pdf_fwd,
                _ => return None,
            }
        } else {
            // `f_hat(v -> pt -> eye[t - 2])`
            pt.f_hat_dirs(
                scene,
                (v.p - pt.p).normalize_or_zero(),
                eye_path.to_prev(t - 1),
            )
        };
        if f == Rgb::ZERO {
            return None;
        }
        let target = if ls.dist.is_infinite() {
            pt.p + ls.wi * (2.0 * scene.radius + (pt.p - scene.center).length())
        } else {
            v.p
        };
        let mut end_v = v;
        end_v.p = target;
        let e = scene.edge(end_v.edge_end(pt.p), pt.edge_end(target), sampler);
        if e.transmittance == Rgb::ZERO {
            return None;
        }
        let cos_pt = cosine_factor(pt, ls.wi);
        let l = pt.beta * f * v.beta * e.transmittance * cos_pt;
        // an infinite light's edge leaves the scene: only the passage of its segments counts
        let pdf_qp = e.pdf_ab;
        let pdf_pq = e.pdf_ba;
        let changed = (t > 1 && self.strategies == Strategies::All)
            .then(|| self.changed_at_light(scene, &v, eye_path, t, (pdf_qp, pdf_pq)));
        Some(Connection {
            l,
            pdf_qp,
            pdf_pq,
            sampled: Some(v),
            raster,
            changed,
        })
    }

    /// [`Bdpt::changed_densities`] of next-event estimation's connection (s = 1, t >= 2) of
    /// light vertex `q` to p = `eye[t - 1]`, with p's per-vertex values: the operands the
    /// vertices would give, so the same bits.
    fn changed_at_light<E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        q: &Vertex,
        eye: &E,
        t: usize,
        (pdf_qp, pdf_pq): (f32, f32),
    ) -> Changed {
        use TransportMode::{Importance, Radiance};
        let p = &eye.vertices()[t - 1];
        let (u, wp) = ((q.p - p.p).normalize_or_zero(), eye.to_prev(t - 1));
        let tech = self.tech;
        Changed {
            pt: q.light_pdf_to(scene, tech, p) * pdf_qp,
            pt_minus: eye
                .prev_area(t - 1)
                .apply(tech.scatter_pdf(scene, p, u, wp, Importance))
                * p.prop_rev,
            qs: to_area(tech.scatter_pdf(scene, p, wp, u, Radiance), p, q) * pdf_pq,
            qs_minus: 0.0,
        }
    }

    /// The light vertex of next-event estimation's sample `ls` of light `li` (seen from
    /// `p_ref`; on primitive `start_prim` of an area light), with its origin density; an
    /// infinite light's vertex is placed beyond the scene along the sampled direction.
    fn light_sample_vertex(
        &self,
        scene: &Scene,
        li: usize,
        ls: &crate::scene::light::LightSample,
        start_prim: Option<u32>,
        p_ref: Vec3,
    ) -> Vertex {
        let light_ref = &scene.lights[li];
        let lm = self.light_media[li];
        let mut v = match light_ref {
            Light::Area { .. } => Vertex::new(
                VertexKind::Light {
                    light: li as u32,
                    prim: start_prim,
                },
                ls.p,
                ls.n,
                lm,
                lm,
            ),
            Light::Point { .. } | Light::Spot { .. } => Vertex::new(
                VertexKind::Light {
                    light: li as u32,
                    prim: None,
                },
                ls.p,
                Vec3::ZERO,
                lm,
                lm,
            ),
            _ => Vertex::new(
                VertexKind::InfiniteLight {
                    light: li as u32,
                    w: ls.wi,
                },
                p_ref + ls.wi * (4.0 * scene.radius + (p_ref - scene.center).length()),
                Vec3::ZERO,
                None,
                None,
            ),
        };
        v.pdf_fwd = v.light_origin_pdf(scene, self.tech);
        v
    }

    /// Strategy t = 1 (light tracing's connection): the light subpath's end `light[s - 1]`
    /// joined to the camera or to a point sampled on the meter of `eye[0]`.
    fn connect_to_sensor<L: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light_path: &L,
        eye: &[Vertex],
        s: usize,
        sampler: &mut Sampler,
    ) -> Option<Connection> {
        let light = light_path.vertices();
        let mut raster = None;
        let qs = &light[s - 1];
        if !qs.is_connectible(scene) || s < 2 {
            return None;
        }
        // the sensor vertex, W_e towards qs and the density of sampling qs's direction from
        // it (the camera's from the one importance evaluation both need)
        let (sensor, we, sensor_pdf) = match eye[0].kind {
            VertexKind::Camera => {
                let cam = scene.camera.as_ref()?;
                let imp = cam.importance((qs.p - cam.eye).normalize_or_zero())?;
                raster = Some(imp.raster);
                let mut v = eye[0];
                v.beta = Rgb::ONE;
                (v, Rgb::splat(imp.we), Some(imp.pdf_dir))
            }
            VertexKind::Meter { meter } => {
                let q = Primitive::Quad(scene.sensors[meter as usize].quad);
                let (p, n) = q.sample_area(sampler.next_2d());
                let mut v = Vertex::new(eye[0].kind, p, n, eye[0].medium_front, eye[0].medium_back);
                v.pdf_fwd = 1.0 / q.area();
                // W_e / p(x) = (1/A) / (1/A)
                v.beta = Rgb::ONE;
                (v, v.importance(scene, qs.p), None)
            }
            _ => return None,
        };
        let area_inv = match sensor.kind {
            VertexKind::Meter { .. } => 1.0 / sensor.pdf_fwd,
            _ => 1.0,
        };
        let d = sensor.p - qs.p;
        let w = d.normalize_or_zero();
        // `f_hat(light[s - 2] -> qs -> sensor)`
        let f = qs.f_hat_dirs(scene, light_path.to_prev(s - 1), w);
        if f == Rgb::ZERO || we == Rgb::ZERO {
            return None;
        }
        let e = scene.edge(qs.edge_end(sensor.p), sensor.edge_end(qs.p), sampler);
        if e.transmittance == Rgb::ZERO {
            return None;
        }
        let g = crate::path::geometry_term::geometry_term_unoccluded(qs, &sensor);
        let l = qs.beta * f * e.transmittance * g * we * area_inv;
        let pdf_qp = e.pdf_ab;
        let pdf_pq = e.pdf_ba;
        let changed = (self.strategies == Strategies::All).then(|| {
            // the sensor's density of -w (`Vertex::pdf_dir` of the sensor)
            let p_to_q = sensor_pdf
                .unwrap_or_else(|| sensor.pdf_dir(scene, self.tech, None, qs.p, Radiance));
            let ends = End {
                p: &sensor,
                p_to_q,
                p_minus: None,
            };
            self.changed_at_walk(scene, light_path, s, ends, (d, w), (pdf_qp, pdf_pq))
        });
        Some(Connection {
            l,
            pdf_qp,
            pdf_pq,
            sampled: Some(sensor),
            raster,
            changed,
        })
    }

    /// Light tracing's connection of y_{s-1} to the meter of `z0` (t = 1), unweighted across
    /// strategies like the rest of light tracing, but with two samplers of the connection
    /// direction w combined by the power heuristic (Veach 1997, sec. 9.2.4):
    ///
    /// - the meter point uniform in the solid angle Omega the meter subtends at y_{s-1}
    ///   ([`IrradianceMeter::connection_from`]: Arvo's spherical triangles; by area when Omega is
    ///   tiny), density p_m(w) = 1 / Omega. Area sampling's G / p = g g' A / d^2 has infinite
    ///   variance for a meter touching a medium (int dz / z^2); by solid angle it is g Omega;
    /// - at a medium vertex, w from the phase function (density p_f), kept when it hits the
    ///   meter's front: the estimate sigma_s tau W_e w_f, bounded whatever the phase function's
    ///   peak, where the first one's f g Omega is not (a photon already heading for the meter
    ///   through a forward HG lobe).
    ///
    /// With w_m = p_m^2 / (p_m^2 + p_f^2) and w_f = 1 - w_m both terms stay below
    /// beta sigma_s tau / A. Returns the contribution and z_0 of the first sampler (or of the
    /// second when the first produced none).
    ///
    /// [`IrradianceMeter::connection_from`]: crate::scene::sensor::IrradianceMeter::connection_from
    fn light_tracing_meter(
        &self,
        scene: &Scene,
        light: &[Vertex],
        s: usize,
        z0: &Vertex,
        sampler: &mut Sampler,
    ) -> Option<(Rgb, Vertex)> {
        let VertexKind::Meter { meter } = z0.kind else {
            return None;
        };
        let qs = &light[s - 1];
        let prev = light[s - 2].p;
        let m = &scene.sensors[meter as usize];
        // both numbers drawn up front, so the streams do not depend on what each sampler finds
        let (u_meter, u_phase) = (sampler.next_2d(), sampler.next_2d());
        // None: y_{s-1} is behind the meter's measuring side
        let conn = m.connection_from(qs.p)?;
        let w_prev = (prev - qs.p).normalize_or_zero();
        let phase = match qs.kind {
            VertexKind::Medium { medium } => Some(scene.media[medium as usize].phase()),
            _ => None,
        };
        let vertex_at = |p: Vec3, pdf_area: f32| {
            let mut v = Vertex::new(z0.kind, p, m.normal(), z0.medium_front, z0.medium_back);
            v.pdf_fwd = pdf_area;
            v.beta = Rgb::ONE;
            v
        };
        // beta f tau W_e g(y_{s-1} -> z_0) / p(w), the unweighted estimate of one direction
        let estimate = |z: &Vertex, pdf_dir: f32, sampler: &mut Sampler| -> Rgb {
            let f = qs.f_hat(scene, prev, z.p);
            let we = z.importance(scene, qs.p);
            if f == Rgb::ZERO || we == Rgb::ZERO || pdf_dir.is_nan() || pdf_dir <= 0.0 {
                return Rgb::ZERO;
            }
            let e = scene.edge(qs.edge_end(z.p), z.edge_end(qs.p), sampler);
            let w = (z.p - qs.p).normalize_or_zero();
            let cos_q = cosine_factor(qs, w);
            qs.beta * f * e.transmittance * we * (cos_q / pdf_dir)
        };
        let mut l = Rgb::ZERO;
        let mut first = None;
        if let Some(mp) = conn.sample(u_meter) {
            let z = vertex_at(mp.p, mp.pdf_area);
            let w = (mp.p - qs.p).normalize_or_zero();
            let p_f = phase.map_or(0.0, |ph| ph.pdf(w_prev, w));
            let p_m = mp.pdf_solid_angle;
            let weight = p_m * p_m / (p_m * p_m + p_f * p_f);
            l += estimate(&z, p_m, sampler) * weight;
            first = Some(z);
        }
        if let Some(ph) = phase {
            let w = ph.sample(w_prev, u_phase).wi;
            if let Some(p) = conn.hit(w) {
                let p_f = ph.pdf(w_prev, w);
                let p_m = conn.pdf_solid_angle(p);
                let z = vertex_at(p, conn.pdf_area(p));
                let weight = p_f * p_f / (p_m * p_m + p_f * p_f);
                l += estimate(&z, p_f, sampler) * weight;
                first.get_or_insert(z);
            }
        }
        first.map(|z| (l, z))
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

/// The power-heuristic weight of strategy (s, t = k + 1 - s) for an explicit path x_0 ... x_k,
/// with every density recomputed from the geometry ([`crate::path::pdf::densities`]): the
/// subpaths are rebuilt as the samplers would have left them, then weighted as in `connect`.
pub fn mis_weight_of_path(
    bdpt: &Bdpt,
    scene: &Scene,
    path: &crate::path::Path,
    s: usize,
    d: &crate::path::pdf::Densities,
) -> f32 {
    let v = &path.vertices;
    let n = v.len();
    let t = n - s;
    if t == 0 {
        return 0.0; // the sensor cannot be hit by chance
    }
    let light: Vec<Vertex> = v[..s]
        .iter()
        .enumerate()
        .map(|(i, x)| {
            let mut x = *x;
            x.pdf_fwd = d.light[i];
            x.pdf_rev = d.eye[i];
            x.prop_rev = if i > 0 { d.prop_down[i - 1] } else { 1.0 };
            x
        })
        .collect();
    let mut eye: Vec<Vertex> = Vec::with_capacity(t);
    for i in (s..n).rev() {
        let mut x = v[i];
        x.pdf_fwd = d.eye[i];
        x.pdf_rev = d.light[i];
        x.prop_rev = if i + 1 < n { d.prop_up[i] } else { 1.0 };
        eye.push(x);
    }
    let (qp, pq) = if s > 0 {
        (d.prop_up[s - 1], d.prop_down[s - 1])
    } else {
        (1.0, 1.0)
    };
    let join = Join {
        s,
        t,
        sampled: None,
        pdf_qp: qp,
        pdf_pq: pq,
    };
    bdpt.mis_weight(scene, &light, &eye, join)
}
