//! Path vertices: on a light (x_0), on a sensor (x_k), on a surface, or in the medium.
//!
//! Each vertex stores what bidirectional methods need to re-evaluate it: its position and
//! normal, the media on both sides, the throughput `beta` of its subpath up to it, and the
//! densities with which it was sampled from its predecessor (`pdf_fwd`) and would be sampled from
//! its successor (`pdf_rev`), both in the vertex's own measure (area on surfaces, volume in the
//! medium) and including the propagation pdf of Table 1 (Pauly et al. sec. 4).

use glam::Vec3;

use crate::bsdf::{Lobe, Normals, TransportMode};
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
    /// The shading normal the BSDF is evaluated with (interpolated on a smooth mesh; `n`
    /// everywhere else).
    pub ns: Vec3,
    /// Throughput of the subpath up to this vertex (its own scattering not included).
    pub beta: Rgb,
    /// Density of this vertex given its predecessor in the subpath that sampled it.
    pub pdf_fwd: f32,
    /// Density of this vertex given its successor (the reverse direction).
    pub pdf_rev: f32,
    /// Propagation pdf (Table 1) of the edge from this vertex back to its subpath predecessor:
    /// the part of the predecessor's `pdf_rev` that depends only on the edge.
    pub prop_rev: f32,
    /// Propagation pdf of the edge from the subpath predecessor to this vertex: the part of
    /// `pdf_fwd` that depends only on the edge, and all of this vertex's density in the
    /// measure of a Dirac predecessor (whose direction has no density: `pdf_fwd` is 0 there),
    /// which the MIS ratios need (`path::subpath::fwd_density`).
    pub prop_fwd: f32,
    /// True when the direction leaving this vertex was sampled from a Dirac lobe.
    pub delta: bool,
    /// The scattering mode used at this vertex (kept by perturbations).
    pub lobe: Lobe,
    /// Medium on the normal's side and behind it (equal where the surface is no interface).
    pub medium_front: Option<u32>,
    pub medium_back: Option<u32>,
}

impl Vertex {
    /// The (light, primitive) of a vertex on an area light: a light vertex, or a surface vertex
    /// an eye path found on an emitter (where the adjoint image and the Metropolis particles
    /// deposit a path's start).
    pub fn area_light_point(&self, scene: &Scene) -> Option<(u32, u32)> {
        match self.kind {
            VertexKind::Light {
                light,
                prim: Some(prim),
            } => Some((light, prim)),
            VertexKind::Surface { prim } => scene.shapes[scene.prim_shape[prim as usize] as usize]
                .light
                .map(|l| (l, prim)),
            _ => None,
        }
    }

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
            ns: n,
            beta: Rgb::ONE,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            prop_rev: 1.0,
            prop_fwd: 1.0,
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
        let mut v = Vertex::new(
            VertexKind::Surface { prim: hit.prim },
            hit.p,
            hit.ng,
            front,
            back,
        );
        v.ns = scene.shading_normal(hit);
        v
    }

    /// The geometric and shading normals, for the BSDF.
    #[inline]
    pub fn normals(&self) -> Normals {
        Normals {
            ng: self.n,
            ns: self.ns,
        }
    }

    /// True for the camera's vertex (pinhole or lens point).
    #[inline]
    pub fn is_camera(&self) -> bool {
        matches!(self.kind, VertexKind::Camera)
    }

    /// True for a medium vertex.
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
            prim: match self.kind {
                VertexKind::Surface { prim }
                | VertexKind::Light {
                    prim: Some(prim), ..
                } => Some(prim),
                _ => None,
            },
            camera: matches!(self.kind, VertexKind::Camera),
        }
    }

    /// The shape's material as declared, for questions about its lobes (Dirac or regular),
    /// which textures never change; [`Vertex::bsdf`] for its values.
    #[inline]
    pub fn material<'a>(&self, scene: &'a Scene) -> Option<&'a crate::bsdf::Bsdf> {
        match self.kind {
            VertexKind::Surface { prim } => scene.shapes[scene.prim_shape[prim as usize] as usize]
                .bsdf
                .as_ref(),
            _ => None,
        }
    }

    /// The BSDF at a surface vertex (`None` elsewhere or at a black emitter); a textured
    /// material is looked up at the vertex's point ([`Scene::bsdf_at`]).
    #[inline]
    pub fn bsdf<'a>(&self, scene: &'a Scene) -> Option<std::borrow::Cow<'a, crate::bsdf::Bsdf>> {
        match self.kind {
            VertexKind::Surface { prim } => scene.bsdf_at(prim, self.p),
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
            VertexKind::Surface { .. } => {
                self.material(scene).is_some_and(|b| b.has_regular_lobe())
            }
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
                Some(b) => b.eval_shaded(wo, wi, self.normals(), TransportMode::Radiance),
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
        let (light, prim, w) = match self.kind {
            VertexKind::Light { light, prim } => (
                light,
                prim.unwrap_or(0),
                (towards - self.p).normalize_or_zero(),
            ),
            // the emission direction is the vertex's own (an environment's radiance depends on
            // it, and the far point's difference would round it)
            VertexKind::InfiniteLight { light, w } => (light, 0, -w),
            _ => return Rgb::ZERO,
        };
        let light = &scene.lights[light as usize];
        emitted_by(light, &scene.prims, prim, (self.p, self.n), w)
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
                        &scene.prims,
                        prim,
                        (self.p, self.n),
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
                .and_then(|c| c.importance(self.p, w))
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
}
