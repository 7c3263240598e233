//! Path vertices: on a light (x_0), on a sensor (x_k), on a surface, or in the medium.
//!
//! Each vertex stores what bidirectional methods need to re-evaluate it: its position and
//! normal, the media on both sides, the throughput `beta` of its subpath up to it, and the
//! densities with which it was sampled from its predecessor (`pdf_fwd`) and would be sampled from
//! its successor (`pdf_rev`), both in the vertex's own measure (area on surfaces, volume in the
//! medium) and including the propagation pdf of Table 1 (Pauly et al. sec. 4).

use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

use super::geometry_term::cosine_factor;
use super::technique::LocalSampling;
use crate::bsdf::{Lobe, TransportMode};
use crate::geometry::Primitive;
use crate::scene::light::emitted_by;
use crate::scene::{EdgeEnd, Light, Scene};
use crate::spectrum::Rgb;

/// What a vertex lies on (the closed set of vertex types).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VertexKind {
    /// The pinhole camera's centre (a Dirac position with W_e per pixel).
    Camera,
    /// A point on irradiance meter `meter`.
    Meter { meter: u32 },
    /// A point on light `light` (`prim` for area lights, `None` for point and spot lights).
    Light { light: u32, prim: Option<u32> },
    /// A directional or environment light's vertex: a point at distance 2R outside the scene in
    /// the direction the light comes from (on the emission disk for a light path's start), and
    /// `w`, that direction (from the scene towards the light), which its radiance and its
    /// density depend on. Its edge has no distance factor in G.
    InfiniteLight { light: u32, w: Vec3 },
    /// A point on a non-null surface.
    Surface { prim: u32 },
    /// A collision point in medium `medium`.
    Medium { medium: u32 },
}

/// A path vertex.
#[derive(Clone, Copy, Debug)]
pub struct Vertex {
    pub kind: VertexKind,
    pub p: Vec3,
    /// Geometric normal on surfaces, area lights and meters; the viewing direction at the
    /// camera; zero in the medium and at point, spot and infinite lights.
    pub n: Vec3,
    /// Throughput of the subpath up to this vertex (its own scattering not included).
    pub beta: Rgb,
    /// Density of this vertex given its predecessor in the subpath that sampled it.
    pub pdf_fwd: f32,
    /// Density of this vertex given its successor (the reverse direction).
    pub pdf_rev: f32,
    /// Propagation pdf (Table 1) of the edge from this vertex back to its subpath predecessor:
    /// the part of the predecessor's `pdf_rev` that depends only on the edge.
    pub prop_rev: f32,
    /// True when the direction leaving this vertex was sampled from a Dirac lobe.
    pub delta: bool,
    /// The scattering mode used at this vertex (kept by perturbations).
    pub lobe: Lobe,
    /// Medium on the normal's side and behind it (equal where the surface is no interface).
    pub medium_front: Option<u32>,
    pub medium_back: Option<u32>,
}

impl Vertex {
    pub fn new(
        kind: VertexKind,
        p: Vec3,
        n: Vec3,
        medium_front: Option<u32>,
        medium_back: Option<u32>,
    ) -> Self {
        Vertex {
            kind,
            p,
            n,
            beta: Rgb::ONE,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            prop_rev: 1.0,
            delta: false,
            lobe: Lobe::Regular,
            medium_front,
            medium_back,
        }
    }

    /// The surface vertex at a hit, with the media on both sides: the shape's interior and
    /// exterior where it separates media, else the medium the ray came through (`medium`).
    pub fn on_surface(scene: &Scene, hit: &crate::geometry::Hit, medium: Option<u32>) -> Self {
        let shape = scene.shape_of(hit);
        let (front, back) = if shape.interface {
            (shape.exterior, shape.interior)
        } else {
            (medium, medium)
        };
        Vertex::new(
            VertexKind::Surface { prim: hit.prim },
            hit.p,
            hit.ng,
            front,
            back,
        )
    }

    #[inline]
    pub fn is_medium(&self) -> bool {
        matches!(self.kind, VertexKind::Medium { .. })
    }

    #[inline]
    pub fn is_sensor(&self) -> bool {
        matches!(self.kind, VertexKind::Camera | VertexKind::Meter { .. })
    }

    /// True for a vertex on an infinite (directional or environment) light.
    #[inline]
    pub fn is_infinite_light(&self) -> bool {
        matches!(self.kind, VertexKind::InfiniteLight { .. })
    }

    /// The medium the vertex looks into in direction `w`.
    #[inline]
    pub fn medium_towards(&self, w: Vec3) -> Option<u32> {
        if self.n == Vec3::ZERO || self.medium_front == self.medium_back || w.dot(self.n) >= 0.0 {
            self.medium_front
        } else {
            self.medium_back
        }
    }

    /// This vertex as one end of an edge towards `other`.
    pub fn edge_end(&self, other: Vec3) -> EdgeEnd {
        let w = other - self.p;
        let surface_n = match self.kind {
            VertexKind::Surface { .. } | VertexKind::Light { prim: Some(_), .. } => self.n,
            _ => Vec3::ZERO,
        };
        EdgeEnd {
            p: self.p,
            n: surface_n,
            medium: self.medium_towards(w),
            in_medium: self.is_medium(),
        }
    }

    /// The BSDF at a surface vertex (`None` elsewhere or at a black emitter).
    pub fn bsdf<'a>(&self, scene: &'a Scene) -> Option<&'a crate::bsdf::Bsdf> {
        match self.kind {
            VertexKind::Surface { prim } => scene.shapes[scene.prim_shape[prim as usize] as usize]
                .bsdf
                .as_ref(),
            _ => None,
        }
    }

    /// True when a connection may end at this vertex: it can scatter towards any direction with
    /// a finite density (not a Dirac lobe, not a directional light).
    pub fn is_connectible(&self, scene: &Scene) -> bool {
        match self.kind {
            VertexKind::Camera | VertexKind::Meter { .. } | VertexKind::Medium { .. } => true,
            VertexKind::Light { .. } => true,
            VertexKind::InfiniteLight { light, .. } => {
                !matches!(scene.lights[light as usize], Light::Directional { .. })
            }
            VertexKind::Surface { .. } => self.bsdf(scene).is_some_and(|b| b.has_regular_lobe()),
        }
    }

    /// f-hat(from -> self -> to) of eq. (6): f_s on a surface, sigma_s f_p in the medium, for light
    /// arriving from point `from` and leaving towards point `to` (the physical, radiance-mode
    /// BSDF; singular lobes give zero).
    // ANCHOR: f_hat
    pub fn f_hat(&self, scene: &Scene, from: Vec3, to: Vec3) -> Rgb {
        let wi = (from - self.p).normalize_or_zero();
        let wo = (to - self.p).normalize_or_zero();
        self.f_hat_dirs(scene, wi, wo)
    }
    // ANCHOR_END: f_hat

    /// [`Vertex::f_hat`] for the unit directions `wi` towards `from` and `wo` towards `to`
    /// (a connection computes them once for both of its ends).
    #[inline]
    pub fn f_hat_dirs(&self, scene: &Scene, wi: Vec3, wo: Vec3) -> Rgb {
        match self.kind {
            VertexKind::Surface { .. } => match self.bsdf(scene) {
                Some(b) => b.eval(wo, wi, self.n, TransportMode::Radiance),
                None => Rgb::ZERO,
            },
            VertexKind::Medium { medium } => {
                let m = &scene.media[medium as usize];
                m.sigma_s(self.p) * m.phase().eval(wo, wi)
            }
            _ => Rgb::ZERO,
        }
    }

    /// L_e(self -> towards) at a light vertex (irradiance for a directional light, intensity for
    /// point and spot lights: their Dirac is consumed by the sampler).
    pub fn emitted(&self, scene: &Scene, towards: Vec3) -> Rgb {
        let (light, w) = match self.kind {
            VertexKind::Light { light, .. } => (light, (towards - self.p).normalize_or_zero()),
            // the emission direction is the vertex's own (an environment's radiance depends on
            // it, and the far point's difference would round it)
            VertexKind::InfiniteLight { light, w } => (light, -w),
            _ => return Rgb::ZERO,
        };
        emitted_by(&scene.lights[light as usize], self.n, w)
    }

    /// Radiance this surface vertex emits towards `towards`, if it is on an area light, or
    /// the volume emittance L_e,V0 at a medium vertex (eq. 1; isotropic, per unit length).
    pub fn surface_emission(&self, scene: &Scene, towards: Vec3) -> Rgb {
        match self.kind {
            VertexKind::Medium { medium } => scene.media[medium as usize].emission(self.p),
            VertexKind::Surface { prim }
            | VertexKind::Light {
                prim: Some(prim), ..
            } => {
                let shape = &scene.shapes[scene.prim_shape[prim as usize] as usize];
                match shape.light {
                    Some(l) => emitted_by(
                        &scene.lights[l as usize],
                        self.n,
                        (towards - self.p).normalize_or_zero(),
                    ),
                    None => Rgb::ZERO,
                }
            }
            _ => Rgb::ZERO,
        }
    }

    /// W_e(from -> self) at a sensor vertex, per pixel (camera) or per meter.
    pub fn importance(&self, scene: &Scene, from: Vec3) -> Rgb {
        let w = (from - self.p).normalize_or_zero();
        match self.kind {
            VertexKind::Camera => scene
                .camera
                .as_ref()
                .and_then(|c| c.importance(w))
                .map_or(Rgb::ZERO, |i| Rgb::splat(i.we)),
            VertexKind::Meter { meter } => {
                let m = &scene.sensors[meter as usize];
                if w.dot(m.normal()) > 0.0 {
                    Rgb::splat(1.0 / Primitive::Quad(m.quad).area())
                } else {
                    Rgb::ZERO
                }
            }
            _ => Rgb::ZERO,
        }
    }

    /// Solid-angle density with which this vertex samples the direction towards `next`, given
    /// its subpath predecessor at `prev` (none for lights and sensors). `mode` is the quantity
    /// of the subpath that samples it (Radiance: an eye subpath walking towards the lights,
    /// Importance: a light subpath): it selects the guide's map (Kristensen 2010, eqs. 5.18,
    /// 5.19) and is ignored when guiding is off. `tech` is the technique that sampled it.
    pub fn pdf_dir(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        prev: Option<Vec3>,
        next: Vec3,
        mode: TransportMode,
    ) -> f32 {
        let wn = (next - self.p).normalize_or_zero();
        match self.kind {
            VertexKind::Camera => scene
                .camera
                .as_ref()
                .and_then(|c| c.importance(wn))
                .map_or(0.0, |i| i.pdf_dir),
            VertexKind::Meter { meter } => {
                let c = wn.dot(scene.sensors[meter as usize].normal());
                c.max(0.0) * FRAC_1_PI
            }
            VertexKind::Light { light, .. } | VertexKind::InfiniteLight { light, .. } => {
                tech.emission_pdf(scene, &scene.lights[light as usize], self.p, self.n, wn)
            }
            VertexKind::Surface { .. } | VertexKind::Medium { .. } => {
                let Some(prev) = prev else { return 0.0 };
                let wp = (prev - self.p).normalize_or_zero();
                tech.scatter_pdf(scene, self, wp, wn, mode)
            }
        }
    }

    /// [`Vertex::pdf_dir`] converted to the measure of `next` (area or volume): times
    /// g(next -> self) / d^2, or g(next) alone when `next` is an infinite light's vertex. The
    /// propagation pdf of the edge is not included.
    pub fn pdf_area(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        prev: Option<Vec3>,
        next: &Vertex,
        mode: TransportMode,
    ) -> f32 {
        if matches!(
            self.kind,
            VertexKind::Light { .. } | VertexKind::InfiniteLight { .. }
        ) {
            return self.light_pdf_to(scene, tech, next);
        }
        if prev.is_none() && self.is_medium() {
            // a medium vertex without predecessor is a light path's volume start x0
            return self.light_pdf_to(scene, tech, next);
        }
        let pdf = self.pdf_dir(scene, tech, prev, next.p, mode);
        to_area(pdf, self, next)
    }

    /// Density (in its own measure) of choosing this light vertex as the start of a light path.
    pub fn light_origin_pdf(&self, scene: &Scene, tech: &dyn LocalSampling) -> f32 {
        // the lights' share of the selection (exactly 1 without emitting media)
        let share = crate::scene::emitters::light_share(scene);
        let pdf = match self.kind {
            // a volume vertex x0 (eq. 5): the media's share times the density per unit volume
            VertexKind::Medium { medium } => {
                return crate::scene::emitters::volume_share(scene)
                    * scene.emitters.pdf(medium, self.p);
            }
            VertexKind::Light { light, prim } => {
                let pmf = scene.light_pmf(light);
                match (&scene.lights[light as usize], prim) {
                    (Light::Area { .. }, Some(p)) => {
                        tech.area_light_start_pdf(scene, light, p, self.p)
                    }
                    _ => pmf,
                }
            }
            // the density of the direction (the position is drawn on a disk per direction and
            // its density enters the next vertex, see `light_pdf_to`)
            VertexKind::InfiniteLight { light, w } => match &scene.lights[light as usize] {
                Light::Environment(env) => scene.light_pmf(light) * env.pdf(w),
                _ => 0.0,
            },
            _ => self.surface_light_origin_pdf(scene, tech),
        };
        pdf * share
    }

    /// For an eye-path vertex that hit an area light: the light-path density of starting there.
    fn surface_light_origin_pdf(&self, scene: &Scene, tech: &dyn LocalSampling) -> f32 {
        let VertexKind::Surface { prim } = self.kind else {
            return 0.0;
        };
        match scene.shapes[scene.prim_shape[prim as usize] as usize].light {
            Some(l) => tech.area_light_start_pdf(scene, l, prim, self.p),
            None => 0.0,
        }
    }

    /// Density (in `next`'s measure) with which a light path starting at this emitting vertex
    /// reaches `next` (direction sampling converted; for infinite lights the disk density times
    /// g(next)). Propagation not included.
    pub fn light_pdf_to(&self, scene: &Scene, tech: &dyn LocalSampling, next: &Vertex) -> f32 {
        let light = match self.kind {
            VertexKind::Light { light, .. } | VertexKind::InfiniteLight { light, .. } => light,
            VertexKind::Surface { prim } => {
                match scene.shapes[scene.prim_shape[prim as usize] as usize].light {
                    Some(l) => l,
                    None => return 0.0,
                }
            }
            // a glowing medium emits uniformly over the sphere
            VertexKind::Medium { medium } if scene.media[medium as usize].emits() => {
                return to_area(0.25 * std::f32::consts::FRAC_1_PI, self, next);
            }
            _ => return 0.0,
        };
        let l = &scene.lights[light as usize];
        if l.is_infinite() {
            let w = (self.p - next.p).normalize_or_zero();
            return cosine_factor(next, w) / (std::f32::consts::PI * scene.radius * scene.radius);
        }
        let wn = (next.p - self.p).normalize_or_zero();
        to_area(tech.emission_pdf(scene, l, self.p, self.n, wn), self, next)
    }
}

/// Solid-angle density `pdf` at `from` converted to the measure of `to`.
#[inline]
pub fn to_area(pdf: f32, from: &Vertex, to: &Vertex) -> f32 {
    AreaFactor::new(from, to).apply(pdf)
}

/// The factor g(to -> from) / d^2 of [`to_area`] for one pair of vertices, kept in its two parts
/// so that a density converted with it rounds exactly as `to_area` rounds it (BDPT keeps one per
/// subpath edge for its weights).
#[derive(Clone, Copy, Debug, Default)]
pub struct AreaFactor {
    /// g(to -> from).
    cos: f32,
    /// The squared distance (0 for coincident vertices: no density).
    d2: f32,
    /// `to` is an infinite light's vertex: no distance and no cosine.
    infinite: bool,
}

impl AreaFactor {
    #[inline]
    pub fn new(from: &Vertex, to: &Vertex) -> Self {
        if to.is_infinite_light() {
            return AreaFactor {
                cos: 1.0,
                d2: 1.0,
                infinite: true,
            };
        }
        let d = to.p - from.p;
        let d2 = d.length_squared();
        let cos = if d2 == 0.0 {
            0.0
        } else {
            cosine_factor(to, d / d2.sqrt())
        };
        AreaFactor {
            cos,
            d2,
            infinite: false,
        }
    }

    /// The density `pdf` (per solid angle at `from`) in the measure of `to`.
    #[inline]
    pub fn apply(self, pdf: f32) -> f32 {
        if self.infinite {
            pdf
        } else if self.d2 == 0.0 {
            0.0
        } else {
            pdf * self.cos / self.d2
        }
    }
}
