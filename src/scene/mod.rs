//! The scene: geometry with its BVH, materials, media, lights, camera and sensors, built from a
//! validated scene file, and the queries every integrator shares: closest hit, propagation
//! through media and null boundaries (Table 1 applied segment by segment), transmittance along a
//! shadow ray, and the medium containing a point.
//! Book: "Scenes" and "Participating media and Table 1".

pub mod build;
pub mod camera;
pub mod emitters;
pub mod envmap;
pub mod file;
pub mod halo;
pub mod light;
pub mod light_tree;
pub mod mitsuba;
pub mod segments;
pub mod sensor;
pub mod source;

pub use camera::Camera;
pub use envmap::EnvMap;
pub use file::{SceneError, SceneFile, SceneSource};
pub use light::{AreaRadiance, Environment, Light};
pub use light_tree::{LightSelection, LightSelectionKind};
pub use segments::{Before, Segment, SegmentEnd, Segments};
pub use sensor::IrradianceMeter;

use glam::Vec3;

use crate::bsdf::{Bsdf, ConductorFresnel};
use crate::geometry::bvh::Passage;
use crate::geometry::{Aabb, Bvh, Hit, Primitive, Ray};
use crate::math::{Distribution1D, Sampler};
use crate::medium::{FreeFlight, Medium};
use crate::spectrum::Rgb;

/// The fog box, compiled into the binary: what `pathspace render` draws without a scene file.
pub const FOG_BOX: &str = include_str!("../../scenes/fog-box.toml");

/// The media of an area light's primitives, in the order of its `prims` (`None`: all in the
/// light's one medium, `Scene::light_media`).
pub type PrimMedia = Option<Box<[Option<u32>]>>;

/// What a shape is made of and what it separates.
#[derive(Clone, Debug)]
pub struct ShapeInfo {
    /// `None` for a black emitter (emission without a material).
    pub bsdf: Option<Bsdf>,
    /// Index into `Scene::lights` when the shape emits.
    pub light: Option<u32>,
    /// Medium behind the geometric normal (inside a closed shape).
    pub interior: Option<u32>,
    /// Medium on the normal's side.
    pub exterior: Option<u32>,
    /// True when the shape declares `interior` or `exterior`: crossing it changes the medium.
    pub interface: bool,
    /// Name for messages (`shapes[3] (box)`).
    pub label: String,
    /// A smooth mesh's corner normals (`smooth_normals`); `None`: shaded by the face normal.
    pub normals: Option<CornerNormals>,
    /// The material's textured reflectance with this shape's (u, v); `None` when constant.
    pub texture: Option<ShapeTexture>,
}

/// The unit normals at the three corners of each triangle of a smooth mesh, for the shading
/// normal at a hit (`Triangle::shading_normal`).
#[derive(Clone, Debug)]
pub struct CornerNormals {
    /// The scene's index of the shape's first primitive.
    pub first_prim: u32,
    /// One entry per primitive of the shape, in order.
    pub corners: Vec<[Vec3; 3]>,
}

/// The textured parameters of a shape's material, and how the shape maps a point to (u, v).
/// The material's constant values stand in wherever no point is known (`info`).
#[derive(Clone, Debug)]
pub struct ShapeTexture {
    /// A `lambert`'s albedo or a plastic's `diffuse` (Mitsuba's `reflectance`,
    /// `diffuse_reflectance`).
    pub reflectance: Option<std::sync::Arc<crate::texture::Texture>>,
    /// A rough conductor's or rough dielectric's `alpha`, the texture's one-channel value
    /// (Mitsuba's `eval_1`, [`crate::texture::Texture::eval_1`]).
    pub alpha: Option<std::sync::Arc<crate::texture::Texture>>,
    /// An anisotropic rough material's `alpha_v` (its `alpha` above is then `alpha_u`), the
    /// texture's one-channel value.
    pub alpha_v: Option<std::sync::Arc<crate::texture::Texture>>,
    /// A conductor's or plastic's `specular` or a dielectric's `specular_reflectance`, the
    /// texture's RGB value (Mitsuba's `eval`, as plugins `conductor`, `roughconductor`,
    /// `plastic`, `roughplastic`, `dielectric`, `roughdielectric`, `thindielectric` scale
    /// their Fresnel term).
    pub specular: Option<std::sync::Arc<crate::texture::Texture>>,
    /// A dielectric's `specular_transmittance`, the texture's RGB value (Mitsuba's `eval`).
    pub transmittance: Option<std::sync::Arc<crate::texture::Texture>>,
    /// A conductor's `eta` and `k`, the textures' RGB values (Mitsuba's `eval`, as plugins
    /// `conductor` and `roughconductor` read them for their Fresnel term), unclamped.
    pub eta: Option<std::sync::Arc<crate::texture::Texture>>,
    pub k: Option<std::sync::Arc<crate::texture::Texture>>,
    /// An anisotropic rough material: its tangent at a point is the shape's dp/du there
    /// ([`UvMap::dp_du`]).
    pub tangent: bool,
    pub uv: UvMap,
}

/// How a shape gives (u, v) to a point of one of its primitives.
#[derive(Clone, Debug)]
pub enum UvMap {
    /// The primitive's own coordinates ([`Primitive::uv`]); a mesh's barycentrics (b1, b2)
    /// when it has no texture coordinates, as Mitsuba 3's meshes.
    Primitive,
    /// Mitsuba 3's `cube` ([-1,1]^3 scaled and moved to `center`, half sides `half`): each face
    /// is the unit square, laid out as `src/shapes/cube.cpp` lists its vertices.
    Cube { center: Vec3, half: Vec3 },
    /// A mesh's texture coordinates at the three corners of each triangle (the scene's
    /// primitives from `first_prim` on), interpolated by the barycentrics as Mitsuba 3's
    /// `Mesh::compute_surface_interaction`: uv0 (1 - b1 - b2) + uv1 b1 + uv2 b2.
    Mesh {
        first_prim: u32,
        corners: std::sync::Arc<[[glam::Vec2; 3]]>,
    },
}

/// Mitsuba 3's `cube`: per face (in its order, by outward normal), the corners of uv (0, 0),
/// (1, 0) and (0, 1) (`src/shapes/cube.cpp`: `position_index` with `side_uv`).
const CUBE_FACES: [(Vec3, [Vec3; 3]); 6] = {
    const fn c(i: u32) -> Vec3 {
        Vec3::new(
            if i & 1 != 0 { 1.0 } else { -1.0 },
            if i & 2 != 0 { 1.0 } else { -1.0 },
            if i & 4 != 0 { 1.0 } else { -1.0 },
        )
    }
    // face s has corners position_index[4s..4s+4] with uv (0,1), (1,1), (1,0), (0,0)
    const IDX: [u32; 24] = [
        1, 5, 4, 0, 3, 2, 6, 7, 1, 3, 7, 5, 5, 7, 6, 4, 4, 6, 2, 0, 3, 1, 0, 2,
    ];
    const N: [Vec3; 6] = [
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(-1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -1.0),
    ];
    let mut out = [(Vec3::ZERO, [Vec3::ZERO; 3]); 6];
    let mut s = 0;
    while s < 6 {
        out[s] = (N[s], [c(IDX[4 * s + 3]), c(IDX[4 * s + 2]), c(IDX[4 * s])]);
        s += 1;
    }
    out
};

/// The normal a (u, v) lookup needs: only the cube's faces (quads) use it.
#[inline]
fn cube_normal(prim: &Primitive) -> Vec3 {
    match prim {
        Primitive::Quad(q) => q.n,
        _ => Vec3::ZERO,
    }
}

impl UvMap {
    /// The (u, v) of point `p` on the scene's primitive `id` (of `prims`).
    #[inline]
    pub fn uv_of(&self, prims: &[Primitive], id: u32, p: Vec3) -> glam::Vec2 {
        let prim = &prims[id as usize];
        self.uv(id, prim, p, cube_normal(prim))
    }

    /// The dp/du of point `p` on the scene's primitive `id` (of `prims`), as [`UvMap::dp_du`].
    #[inline]
    pub fn dp_du_of(&self, prims: &[Primitive], id: u32, p: Vec3) -> Vec3 {
        let prim = &prims[id as usize];
        self.dp_du(id, prim, p, cube_normal(prim))
    }

    /// The (u, v) of point `p` on primitive `prim` (index `id`, with unit normal `n`).
    pub fn uv(&self, id: u32, prim: &Primitive, p: Vec3, n: Vec3) -> glam::Vec2 {
        match self {
            UvMap::Primitive => prim.uv(p),
            UvMap::Mesh {
                first_prim,
                corners,
            } => {
                let b = prim.uv(p);
                let [t0, t1, t2] = corners[(id - first_prim) as usize];
                t0 * (1.0 - b.x - b.y) + t1 * b.x + t2 * b.y
            }
            &UvMap::Cube { center, half } => {
                let local = (p - center) / half;
                let face = CUBE_FACES
                    .iter()
                    .max_by(|a, b| a.0.dot(n).total_cmp(&b.0.dot(n)))
                    .map_or([Vec3::ZERO; 3], |f| f.1);
                let [o, eu, ev] = face;
                // the edges are 2 long: a coordinate is the projection over 4
                let rel = local - o;
                glam::Vec2::new(rel.dot(eu - o) / 4.0, rel.dot(ev - o) / 4.0)
            }
        }
    }
}

impl UvMap {
    /// dp/du at point `p` of primitive `prim` (index `id`, unit normal `n`) in this map's
    /// (u, v), as Mitsuba 3 computes it: [`Primitive::dp_du`]; a cube face's edge from its uv
    /// (0, 0) corner to its (1, 0) one; a mesh's from the corners' texture coordinates
    /// (`Mesh::compute_surface_interaction`), or Duff et al.'s first axis around the face
    /// normal where they are degenerate (zero determinant).
    pub fn dp_du(&self, id: u32, prim: &Primitive, p: Vec3, n: Vec3) -> Vec3 {
        match (self, prim) {
            (
                UvMap::Mesh {
                    first_prim,
                    corners,
                },
                Primitive::Triangle(t),
            ) => {
                let [t0, t1, t2] = corners[(id - first_prim) as usize];
                let (d0, d1) = (t1 - t0, t2 - t0);
                let det = d0.x * d1.y - d0.y * d1.x;
                if det == 0.0 {
                    let face = t.e1().cross(t.e2()).normalize_or_zero();
                    return crate::math::Frame::from_normal(face).s;
                }
                (d1.y * t.e1() - d0.y * t.e2()) / det
            }
            (&UvMap::Cube { half, .. }, _) => {
                let face = CUBE_FACES
                    .iter()
                    .max_by(|a, b| a.0.dot(n).total_cmp(&b.0.dot(n)))
                    .map_or([Vec3::ZERO; 3], |f| f.1);
                (face[1] - face[0]) * half
            }
            _ => prim.dp_du(p),
        }
    }
}

impl ShapeInfo {
    /// True for a null (index-matched) boundary: tracing passes through it.
    pub fn is_null(&self) -> bool {
        matches!(self.bsdf, Some(Bsdf::Null(_)))
    }

    /// The medium a ray leaving this shape along `wi` starts in, for a ray that arrived along
    /// `-wo` in medium `before`: the medium behind the shape when `wi` crosses it (a
    /// refraction), else `before`. The sampled walks and next-event estimation share it.
    #[inline]
    pub fn medium_across(&self, wo: Vec3, wi: Vec3, ng: Vec3, before: Option<u32>) -> Option<u32> {
        if wi.dot(ng) * wo.dot(ng) < 0.0 {
            self.medium_after(wi, ng, before)
        } else {
            before
        }
    }

    /// The medium a ray travelling along `d` is in after crossing this shape at a point with
    /// normal `ng`, given the medium it was in before.
    #[inline]
    pub fn medium_after(&self, d: Vec3, ng: Vec3, before: Option<u32>) -> Option<u32> {
        if !self.interface {
            return before;
        }
        if d.dot(ng) < 0.0 {
            self.interior
        } else {
            self.exterior
        }
    }
}

/// Where a ray's propagation ended.
#[derive(Clone, Copy, Debug)]
pub enum Event {
    /// A collision inside `medium` at `p` (a medium vertex), at ray parameter `t` of the
    /// propagated ray (the segments' own parameter, so a caller can place it among them).
    Medium {
        p: Vec3,
        t: f32,
        medium: u32,
        sigma_s: Rgb,
    },
    /// A non-null surface; `medium` is the medium the ray travelled in just before.
    Surface { hit: Hit, medium: Option<u32> },
    /// The ray left the scene.
    Escape,
}

/// The result of propagating a ray until an interaction (Table 1 per medium segment).
#[derive(Clone, Copy, Debug)]
pub struct Propagation {
    pub event: Event,
    /// Transmittance along the whole way, per channel.
    pub transmittance: Rgb,
    /// Product of the free-flight pdfs of every segment (density of the collision times the
    /// passage probabilities of the segments before it).
    pub pdf: f32,
    /// The same for the reverse walk, from where the ray ended back to its origin (a collision
    /// density at the origin if it is a medium vertex); only computed by
    /// [`Scene::propagate_bidirectional`], 1 otherwise.
    pub pdf_rev: f32,
}

impl Propagation {
    /// A ray trapped by more than [`segments::MAX_NULL_CROSSINGS`] null crossings: no light
    /// passes.
    const TRAPPED: Propagation = Propagation {
        event: Event::Escape,
        transmittance: Rgb::ZERO,
        pdf: 1.0,
        pdf_rev: 1.0,
    };

    /// transmittance (times sigma_s at a medium vertex) over pdf: the throughput factor.
    #[inline]
    pub fn weight(&self) -> Rgb {
        if self.pdf <= 0.0 {
            return Rgb::ZERO;
        }
        match self.event {
            Event::Medium { sigma_s, .. } => self.transmittance * sigma_s / self.pdf,
            _ => self.transmittance / self.pdf,
        }
    }
}

/// A [`Propagation`] for an estimator that needs only its event and throughput factor, from
/// [`Scene::propagate_weight_from`]: its transmittance and pdf may share an unknown factor
/// (the skipped optical depth of grey tracked media), so they are not exposed.
#[derive(Clone, Copy, Debug)]
pub struct WeightedPropagation(Propagation);

impl WeightedPropagation {
    /// Where the ray's propagation ended.
    #[inline]
    pub fn event(&self) -> Event {
        self.0.event
    }

    /// [`Propagation::weight`] (equal to rounding where an optical depth was skipped).
    #[inline]
    pub fn weight(&self) -> Rgb {
        self.0.weight()
    }
}

/// Transmittance (with visibility) and the propagation pdfs of an edge in both directions.
#[derive(Clone, Copy, Debug)]
pub struct EdgeEval {
    pub transmittance: Rgb,
    pub pdf_ab: f32,
    pub pdf_ba: f32,
}

/// One end of an edge: a point, its surface normal (zero in a medium or at a point light), the
/// medium the edge leaves it into, and whether it is a medium vertex; the primitive it lies on
/// and whether it is the camera, for hidden emitters ([`Scene::camera_bvh`]).
#[derive(Clone, Copy, Debug)]
pub struct EdgeEnd {
    pub p: Vec3,
    pub n: Vec3,
    pub medium: Option<u32>,
    pub in_medium: bool,
    pub prim: Option<u32>,
    pub camera: bool,
}

/// A scene ready to render.
pub struct Scene {
    pub prims: Vec<Primitive>,
    /// Shape index of every primitive.
    pub prim_shape: Vec<u32>,
    /// Whether a primitive is opaque (wins coplanar ties and blocks shadow rays).
    pub prim_opaque: Vec<bool>,
    pub bvh: Bvh,
    /// The null boundaries of `bvh` alone: once an any-hit query has found no opaque surface
    /// along an edge, only these remain to cut it into medium segments (`Scene::edge`).
    pub boundary_bvh: Bvh,
    /// The scene as the camera sees it before its first scattering vertex when emitters are
    /// hidden: `bvh` without the emitter shapes, which are transparent to those rays (Mitsuba
    /// 3.9.1's `skip_area_emitters`); `None` without `hide_emitters` or without area lights.
    pub camera_bvh: Option<Bvh>,
    /// True when every medium's transmittance is a closed form (homogeneous media): a shadow
    /// ray draws no random numbers, so an occluded one may stop before its first segment.
    pub closed_form_tau: bool,
    pub shapes: Vec<ShapeInfo>,
    pub media: Vec<Medium>,
    pub medium_names: Vec<String>,
    pub lights: Vec<Light>,
    /// Light selection proportional to power.
    pub light_distr: Distribution1D,
    /// Index of the environment light, if any (at most one).
    pub environment: Option<u32>,
    /// The medium around each light, where its light subpaths start (BDPT's walks and
    /// next-event estimation, MLT's light vertices), found once when the scene is built;
    /// `None` in vacuum and for the infinite lights.
    pub light_media: Vec<Option<u32>>,
    /// For an area light whose primitives lie in different media (a lamp on the floor of a
    /// fog, one face emitting into the fog and one under the floor), the medium of each of its
    /// primitives, in the order of its `prims`; `None` where `light_media` holds for all.
    pub light_prim_media: Vec<PrimMedia>,
    pub camera: Option<Camera>,
    pub camera_medium: Option<u32>,
    /// The emitting media as lights (L_e,V0 of eq. 1): empty unless a medium glows.
    pub emitters: emitters::VolumeEmitters,
    pub sensors: Vec<IrradianceMeter>,
    pub bounds: Aabb,
    pub center: Vec3,
    pub radius: f32,
    /// True when any null boundary exists (otherwise a shadow ray is one any-hit query, with
    /// no segments to walk).
    pub has_null: bool,
    /// Null faces left out of the BVH because a coplanar wall covers them (`build::hidden`).
    pub hidden_faces: usize,
    /// The scene file's `hide_emitters`: the fewest scattering vertices a measured path has
    /// ([`Scene::min_depth`]).
    pub hide_emitters: bool,
    /// Hash of the scene file text.
    pub hash: u64,
    pub source_name: String,
}

impl Scene {
    /// The fewest scattering vertices (surface or medium, null boundaries not counted) a path
    /// needs to be measured: 1 with `hide_emitters`, which removes every path whose camera and
    /// emitter are adjacent (Mitsuba 3's "directly visible emitters", seen through null
    /// boundaries and media too, as its `volpath` counts only scattering in its depth), else 0.
    #[inline]
    pub fn min_depth(&self) -> u32 {
        self.hide_emitters as u32
    }

    /// True when `prim` belongs to an emitter shape (an area light's).
    #[inline]
    pub fn on_emitter(&self, prim: u32) -> bool {
        self.shapes[self.prim_shape[prim as usize] as usize]
            .light
            .is_some()
    }

    /// Closest hit along the ray, null boundaries included.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        self.bvh
            .intersect(&self.prims, &self.prim_opaque, ray, t_max)
    }

    #[inline]
    pub fn shape_of(&self, hit: &Hit) -> &ShapeInfo {
        &self.shapes[self.prim_shape[hit.prim as usize] as usize]
    }

    /// The shading normal at a hit: interpolated from the corner normals on a smooth mesh, the
    /// geometric normal elsewhere (bitwise, so flat scenes take no other path).
    #[inline]
    pub fn shading_normal(&self, hit: &Hit) -> Vec3 {
        let Some(cn) = &self.shape_of(hit).normals else {
            return hit.ng;
        };
        match &self.prims[hit.prim as usize] {
            Primitive::Triangle(t) => {
                t.shading_normal(&cn.corners[(hit.prim - cn.first_prim) as usize], hit.p)
            }
            _ => hit.ng,
        }
    }

    /// The BSDF at point `p` of primitive `prim`: the shape's material, with its textured
    /// reflectance looked up at the point's (u, v); borrowed, unchanged, when nothing is
    /// textured (`None` at a black emitter).
    #[inline]
    pub fn bsdf_at(&self, prim: u32, p: Vec3) -> Option<std::borrow::Cow<'_, Bsdf>> {
        let shape = &self.shapes[self.prim_shape[prim as usize] as usize];
        let bsdf = shape.bsdf.as_ref()?;
        let Some(t) = &shape.texture else {
            return Some(std::borrow::Cow::Borrowed(bsdf));
        };
        Some(std::borrow::Cow::Owned(self.textured(bsdf, t, prim, p)))
    }

    /// `bsdf` with `t`'s values at `p` (kept out of line: untextured scenes never call it).
    #[inline(never)]
    fn textured(&self, bsdf: &Bsdf, t: &ShapeTexture, id: u32, p: Vec3) -> Bsdf {
        let uv = t.uv.uv_of(&self.prims, id, p);
        let mut out = bsdf.clone();
        if let Some(r) = &t.reflectance {
            let value = r.eval(uv);
            match &mut out {
                Bsdf::Lambert(l) => l.albedo = value,
                Bsdf::Plastic(m) => m.diffuse = value,
                // its sampling weight stays the texture mean's, as Mitsuba's
                Bsdf::RoughPlastic(m) => m.diffuse = value,
                _ => {}
            }
        }
        if t.tangent {
            let anisotropy = match &mut out {
                Bsdf::RoughConductor(m) => m.anisotropy.as_mut(),
                Bsdf::RoughDielectric(m) => m.anisotropy.as_mut(),
                _ => None,
            };
            if let Some(a) = anisotropy {
                a.tangent = t.uv.dp_du_of(&self.prims, id, p);
                if let Some(v) = &t.alpha_v {
                    a.alpha_v = v.eval_1(uv);
                }
            }
        }
        if let Some(a) = &t.alpha {
            let alpha = a.eval_1(uv);
            match &mut out {
                Bsdf::RoughConductor(m) => m.alpha = alpha,
                Bsdf::RoughDielectric(m) => m.alpha = alpha,
                _ => {}
            }
        }
        if let Some(s) = &t.specular {
            // the value only: a conductor's sampling never reads `specular`, a rough plastic's
            // keeps the weight of the texture's mean (Mitsuba's); a smooth plastic's lobe
            // choice follows the point's colours (same expectation, same values)
            let value = s.eval(uv);
            match &mut out {
                Bsdf::Conductor(m) => m.specular = value,
                Bsdf::RoughConductor(m) => m.specular = value,
                Bsdf::Plastic(m) => m.specular = value,
                Bsdf::RoughPlastic(m) => m.specular = value,
                // a dielectric's lobe choice stays Fresnel's (Mitsuba's)
                Bsdf::Dielectric(m) => m.specular.reflectance = value,
                Bsdf::ThinDielectric(m) => m.specular.reflectance = value,
                Bsdf::RoughDielectric(m) => m.specular.reflectance = value,
                _ => {}
            }
        }
        if let Some(s) = &t.transmittance {
            let value = s.eval(uv);
            match &mut out {
                Bsdf::Dielectric(m) => m.specular.transmittance = value,
                Bsdf::ThinDielectric(m) => m.specular.transmittance = value,
                Bsdf::RoughDielectric(m) => m.specular.transmittance = value,
                _ => {}
            }
        }
        if t.eta.is_some() || t.k.is_some() {
            // the Fresnel term only: no density of a conductor reads the index
            let at = |t: &Option<std::sync::Arc<crate::texture::Texture>>, c: Rgb| {
                t.as_ref().map_or(c, |t| t.eval(uv))
            };
            match &mut out {
                Bsdf::Conductor(m) => (m.eta, m.k) = (at(&t.eta, m.eta), at(&t.k, m.k)),
                Bsdf::RoughConductor(m) => {
                    if let ConductorFresnel::Complex { eta, k } = &mut m.fresnel {
                        (*eta, *k) = (at(&t.eta, *eta), at(&t.k, *k));
                    }
                }
                _ => {}
            }
        }
        out
    }

    /// Propagates `ray`, starting in `medium`, through media and null boundaries until a
    /// collision, a non-null surface or escape.
    // ANCHOR: propagate
    pub fn propagate(
        &self,
        ray: Ray,
        lead: f32,
        medium: Option<u32>,
        sampler: &mut Sampler,
    ) -> Propagation {
        self.propagate_from(ray, lead, medium, false, sampler)
    }

    /// [`Scene::propagate`] of a ray from the camera before its first scattering vertex when
    /// `from_camera` ([`Segments::from_camera`]: hidden emitters are transparent to it).
    pub fn propagate_from(
        &self,
        ray: Ray,
        lead: f32,
        medium: Option<u32>,
        from_camera: bool,
        sampler: &mut Sampler,
    ) -> Propagation {
        let next = self.flights_from(ray, (lead, medium, from_camera), full);
        self.propagate_with::<false>(ray, next, false, sampler)
    }

    /// [`Scene::propagate`] along `segments`, the ones [`Segments`] gave for the same ray, lead
    /// and medium (kept by a caller that walked them already: the same events and random
    /// numbers without a second set of intersection queries).
    pub fn propagate_along(
        &self,
        ray: Ray,
        segments: impl Iterator<Item = Segment>,
        sampler: &mut Sampler,
    ) -> Propagation {
        self.propagate_with::<false>(ray, self.flights_along(ray, segments, full), false, sampler)
    }

    /// [`Scene::propagate`] that also computes the reverse propagation pdf, for bidirectional
    /// methods. `origin_in_medium` tells whether the ray starts at a medium vertex,
    /// `from_camera` whether at the camera ([`Scene::propagate_from`]).
    pub fn propagate_bidirectional(
        &self,
        ray: Ray,
        lead: f32,
        medium: Option<u32>,
        (origin_in_medium, from_camera): (bool, bool),
        sampler: &mut Sampler,
    ) -> Propagation {
        let next = self.flights_from(ray, (lead, medium, from_camera), full);
        self.propagate_with::<true>(ray, next, origin_in_medium, sampler)
    }

    /// The segments of an unbounded ray from a vertex (`lead` past its surface, starting in
    /// `medium`, from the camera or not: hidden emitters), each with its flight by `flight`,
    /// as the walk reaches them ([`Scene::next_flight`]).
    fn flights_from<'a>(
        &'a self,
        ray: Ray,
        (lead, medium, from_camera): (f32, Option<u32>, bool),
        flight: impl Fn(&Medium, &Ray, f32, &mut Sampler) -> FreeFlight + Copy + 'a,
    ) -> impl FnMut(&mut Sampler) -> Flight + 'a {
        let mut segments = Segments::new(self, ray, medium, f32::INFINITY)
            .lead(lead)
            .from_camera(from_camera);
        move |sampler: &mut Sampler| self.next_flight(ray, &mut segments, flight, sampler)
    }

    /// [`Scene::propagate_from`] for an estimator that needs only the throughput factor: the
    /// same event from the same random numbers, the weight equal to rounding, each segment's
    /// flight by [`Medium::sample_free_flight_weight`] (no exact optical depth in a grey tracked
    /// inhomogeneous medium).
    pub fn propagate_weight_from(
        &self,
        ray: Ray,
        lead: f32,
        medium: Option<u32>,
        from_camera: bool,
        sampler: &mut Sampler,
    ) -> WeightedPropagation {
        let next = self.flights_from(ray, (lead, medium, from_camera), weight);
        WeightedPropagation(self.propagate_with::<false>(ray, next, false, sampler))
    }

    /// [`Scene::propagate_along`] for an estimator that needs only the throughput factor
    /// ([`Scene::propagate_weight_from`]).
    pub fn propagate_weight_along(
        &self,
        ray: Ray,
        segments: impl Iterator<Item = Segment>,
        sampler: &mut Sampler,
    ) -> WeightedPropagation {
        let next = self.flights_along(ray, segments, weight);
        WeightedPropagation(self.propagate_with::<false>(ray, next, false, sampler))
    }

    /// The next segment of `segments` and its free flight by `flight`. In a homogeneous medium
    /// the flight is drawn first, so that the intersection query can stop at the collision
    /// ([`Segments::next_before`]: a collision needs no knowledge of the surfaces beyond it);
    /// the outcome and the random numbers are those of drawing it after the query. (A tracked
    /// medium's walk draws random numbers up to the segment's end, so it is drawn after.)
    #[inline]
    fn next_flight(
        &self,
        ray: Ray,
        segments: &mut Segments,
        flight: impl Fn(&Medium, &Ray, f32, &mut Sampler) -> FreeFlight,
        sampler: &mut Sampler,
    ) -> Flight {
        let (t0, first) = (segments.start(), segments.first());
        let Some(m) = segments.medium() else {
            return segments
                .next()
                .map_or(Flight::Trapped, |seg| Flight::Segment(seg, None));
        };
        match &self.media[m as usize] {
            Medium::Homogeneous(h) => {
                // the random numbers in the order `Medium::sample_free_flight` draws them
                let (u_channel, u) = (sampler.next_f32(), sampler.next_f32());
                let collision = h.sample_free_flight(f32::INFINITY, u_channel, u);
                let seg = match segments.next_before(collision.t) {
                    Before::Beyond => {
                        let (medium, ff) = (m, collision);
                        return Flight::Collided {
                            t0,
                            medium,
                            first,
                            ff,
                        };
                    }
                    Before::Segment(seg) => seg,
                };
                let Some(seg) = seg else {
                    return Flight::Trapped;
                };
                let len = seg.t1 - seg.t0;
                let ff = if collision.t < len {
                    collision
                } else {
                    h.sample_free_flight(len, u_channel, u)
                };
                Flight::Segment(seg, Some(ff))
            }
            med => {
                let Some(seg) = segments.next() else {
                    return Flight::Trapped;
                };
                let sr = Ray::new(ray.at(t0), ray.d);
                Flight::Segment(seg, Some(flight(med, &sr, seg.t1 - seg.t0, sampler)))
            }
        }
    }

    /// [`Scene::next_flight`] along segments walked already.
    fn flights_along<'a>(
        &'a self,
        ray: Ray,
        mut segments: impl Iterator<Item = Segment> + 'a,
        flight: impl Fn(&Medium, &Ray, f32, &mut Sampler) -> FreeFlight + 'a,
    ) -> impl FnMut(&mut Sampler) -> Flight + 'a {
        move |sampler: &mut Sampler| {
            let Some(seg) = segments.next() else {
                return Flight::Trapped;
            };
            let ff = seg.medium.map(|m| {
                let sr = Ray::new(ray.at(seg.t0), ray.d);
                flight(&self.media[m as usize], &sr, seg.t1 - seg.t0, sampler)
            });
            Flight::Segment(seg, ff)
        }
    }

    /// The segment walk of [`Scene::propagate`] (Table 1 on each medium segment;
    /// memorylessness makes the segments independent), each segment and its flight from
    /// `next`.
    #[inline]
    fn propagate_with<const REV: bool>(
        &self,
        ray: Ray,
        mut next: impl FnMut(&mut Sampler) -> Flight,
        origin_in_medium: bool,
        sampler: &mut Sampler,
    ) -> Propagation {
        let mut transmittance = Rgb::ONE;
        let mut pdf = 1.0f32;
        let mut pdf_rev = 1.0f32;
        loop {
            let (t0, first, medium, ff, seg) = match next(sampler) {
                Flight::Trapped => return Propagation::TRAPPED,
                Flight::Collided {
                    t0,
                    medium,
                    first,
                    ff,
                } => (t0, first, Some(medium), Some(ff), None),
                Flight::Segment(seg, ff) => (seg.t0, seg.first, seg.medium, ff, Some(seg)),
            };
            if let (Some(ff), Some(m)) = (ff, medium) {
                transmittance *= ff.transmittance;
                pdf *= ff.pdf;
                if REV {
                    // the reverse walk passes this segment, or collides at its far end (the
                    // origin) when the origin is a medium vertex
                    let back = Ray::new(Ray::new(ray.at(t0), ray.d).at(ff.t), -ray.d);
                    let med = &self.media[m as usize];
                    pdf_rev *= med.free_flight_pdf(&back, ff.t, first && origin_in_medium);
                }
                if ff.scattered {
                    let mut p = collided(ray, t0, m, ff, (transmittance, pdf));
                    p.pdf_rev = pdf_rev;
                    return p;
                }
            }
            if let Some(event) = seg.as_ref().and_then(segment_event) {
                return Propagation {
                    event,
                    transmittance,
                    pdf,
                    pdf_rev,
                };
            }
        }
    }
    // ANCHOR_END: propagate

    /// Whether an opaque surface lies along `ray` at t in (0, t_max): one any-hit query,
    /// null boundaries ignored. A segment walk over the same range would end at such a surface
    /// (a boundary at the same t loses the tie to it), so `true` means zero transmittance.
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.bvh
            .occluded(&self.prims, &self.prim_opaque, ray, t_max)
    }

    /// [`Scene::occluded`] that also tells whether the ray crosses a null boundary when nothing
    /// blocks it ([`Bvh::passage`]): a shadow ray that crosses none is one medium segment.
    #[inline]
    pub fn passage(&self, ray: &Ray, t_max: f32) -> Passage {
        self.bvh.passage(&self.prims, &self.prim_opaque, ray, t_max)
    }

    /// [`Scene::occluded`] as the camera sees before its first scattering vertex when
    /// `from_camera` (hidden emitters left out, [`Scene::camera_bvh`]).
    #[inline]
    pub fn occluded_from(&self, ray: &Ray, t_max: f32, from_camera: bool) -> bool {
        let bvh = match &self.camera_bvh {
            Some(b) if from_camera => b,
            _ => &self.bvh,
        };
        bvh.occluded(&self.prims, &self.prim_opaque, ray, t_max)
    }

    /// Transmittance from `o` along unit `d` over distance `dist` (may be infinite), starting in
    /// `medium`, through null boundaries; zero when an opaque surface is in the way. This is
    /// the tau of eq. (3) times the visibility V.
    // ANCHOR: transmittance
    pub fn transmittance(
        &self,
        o: Vec3,
        d: Vec3,
        dist: f32,
        medium: Option<u32>,
        sampler: &mut Sampler,
    ) -> Rgb {
        let ray = Ray::new(o, d);
        if !self.has_null {
            // no boundary to cross: one any-hit query settles visibility
            if self.occluded(&ray, dist) {
                return Rgb::ZERO;
            }
            return match medium {
                Some(m) => self.media[m as usize].transmittance(&ray, dist, sampler),
                None => Rgb::ONE,
            };
        }
        let mut segments = Segments::new(self, ray, medium, dist);
        if self.closed_form_tau {
            segments = match self.passage(&ray, dist) {
                Passage::Blocked => return Rgb::ZERO,
                Passage::Crossing => segments.boundaries_only(),
                Passage::Clear => segments.clear_ahead(),
            };
        }
        // otherwise the walk below meets any opaque occluder itself, after drawing the random
        // numbers of the segments before it, as it always has (same images)
        let mut tr = Rgb::ONE;
        for seg in segments {
            if let Some(m) = seg.medium {
                let sr = Ray::new(ray.at(seg.t0), d);
                tr *= self.media[m as usize].transmittance(&sr, seg.t1 - seg.t0, sampler);
                if tr == Rgb::ZERO {
                    return tr;
                }
            }
            match seg.end {
                SegmentEnd::Null(_) => {}
                SegmentEnd::Open => return tr,
                SegmentEnd::Surface(_) => return Rgb::ZERO,
            }
        }
        Rgb::ZERO
    }
    // ANCHOR_END: transmittance

    /// The straight way from `o` (`lead` behind it the vertex itself) to the point `x` of
    /// medium `m`, starting in `medium`: its transmittance (eq. 3, with visibility) and the
    /// free-flight density of a walk from the vertex colliding at `x` (the passage
    /// probabilities of the segments before it times the collision density there, Table 1, per
    /// unit length). `None` when an opaque surface is in the way or `x` is not in `m`. For
    /// next-event estimation toward an emitting medium (eq. 5 with x0 a volume vertex).
    pub fn volume_edge(
        &self,
        (o, lead): (Vec3, f32),
        x: Vec3,
        medium: Option<u32>,
        m: u32,
        sampler: &mut Sampler,
    ) -> Option<(Rgb, f32)> {
        let dist = (x - o).length();
        let ray = Ray::new(o, (x - o) / dist);
        let (mut tr, mut pdf) = (Rgb::ONE, 1.0f32);
        for seg in Segments::new(self, ray, medium, dist).lead(lead) {
            let last = matches!(seg.end, SegmentEnd::Open);
            if let Some(k) = seg.medium {
                let (sr, len) = (Ray::new(ray.at(seg.t0), ray.d), seg.t1 - seg.t0);
                let med = &self.media[k as usize];
                tr *= med.transmittance(&sr, len, sampler);
                pdf *= med.free_flight_pdf(&sr, len, last);
            }
            match seg.end {
                SegmentEnd::Null(_) => {}
                SegmentEnd::Open => return (seg.medium == Some(m)).then_some((tr, pdf)),
                SegmentEnd::Surface(_) => return None,
            }
        }
        None
    }

    /// Transmittance and propagation pdfs of the straight edge from `a` to `b` (a connection in
    /// BDPT, or a re-evaluated edge in MLT): `pdf_ab` is the propagation pdf (Table 1) of
    /// reaching `b` from `a` (a collision density if `b_in_medium`, else the passage
    /// probabilities), `pdf_ba` the same from `b` to `a`. Transmittance includes visibility.
    // ANCHOR: edge
    pub fn edge(&self, a: EdgeEnd, b: EdgeEnd, sampler: &mut Sampler) -> EdgeEval {
        let closed_form = self.closed_form_tau;
        self.edge_with(a, b, closed_form, |med, ray, len| {
            med.transmittance(ray, len, sampler)
        })
    }

    /// [`Scene::edge`] with the exact transmittance of every medium segment
    /// (`Medium::transmittance_exact`): deterministic, for MLT's target function.
    pub fn edge_exact(&self, a: EdgeEnd, b: EdgeEnd) -> EdgeEval {
        self.edge_with(a, b, true, |med, ray, len| {
            med.transmittance_exact(ray, len)
        })
    }

    /// [`Scene::edge_exact`] by the plain segment walk: closest-hit queries over the whole
    /// tree, without the any-hit query first. The two give the same bits (`tests/spec/scene.rs`);
    /// this one is the reference the shortcut is checked against.
    pub fn edge_exact_walked(&self, a: EdgeEnd, b: EdgeEnd) -> EdgeEval {
        self.edge_with(a, b, false, |med, ray, len| {
            med.transmittance_exact(ray, len)
        })
    }

    /// [`Scene::edge`] with `tau(medium, ray, length)` giving each medium segment's
    /// transmittance (generic, not `dyn`: BDPT calls it for every connection). With `shortcut`
    /// one any-hit query settles visibility first and the walk queries only the null
    /// boundaries; only for a `tau` that draws no random numbers, since an occluded edge then
    /// calls it fewer times than the walk would.
    fn edge_with(
        &self,
        a: EdgeEnd,
        b: EdgeEnd,
        shortcut: bool,
        mut tau: impl FnMut(&crate::medium::Medium, &Ray, f32) -> Rgb,
    ) -> EdgeEval {
        let zero = EdgeEval {
            transmittance: Rgb::ZERO,
            pdf_ab: 0.0,
            pdf_ba: 0.0,
        };
        let full = b.p - a.p;
        let d = full.normalize_or_zero();
        if d == Vec3::ZERO || !d.is_finite() {
            return zero;
        }
        // lift surface endpoints off their surfaces so neither counts as an occluder
        let o = if a.n != Vec3::ZERO {
            crate::geometry::offset_origin(a.p, a.n, d)
        } else {
            a.p
        };
        let target = if b.n != Vec3::ZERO {
            crate::geometry::offset_origin(b.p, b.n, -d)
        } else {
            b.p
        };
        // the query runs between the lifted points themselves: a ray along the unlifted
        // direction, stopped at the lifted target's projection, ends behind b's surface when
        // both ends see each other at more than 45 degrees from their normals, and the
        // target's own surface would occlude the edge
        let lifted = target - o;
        let dist = lifted.length();
        if dist.is_nan() || dist <= 0.0 || !dist.is_finite() {
            return zero;
        }
        let d = lifted / dist;
        // medium segments are measured between the true end points, the lifted ones only serve
        // the intersection queries (so f_j and the samplers' pdfs see the same lengths)
        let lead_a = (o - a.p).dot(d);
        let lead_b = (b.p - target).dot(d);
        let (a_in_medium, b_in_medium) = (a.in_medium, b.in_medium);
        let ray = Ray::new(o, d);
        let mut out = EdgeEval {
            transmittance: Rgb::ONE,
            pdf_ab: 1.0,
            pdf_ba: 1.0,
        };
        // the camera's edge to its first vertex when emitters are hidden: through emitter
        // shapes, and never ending on one
        let camera = self.camera_bvh.is_some() && (a.camera || b.camera);
        if camera
            && [a.prim, b.prim]
                .into_iter()
                .flatten()
                .any(|p| self.on_emitter(p))
        {
            return zero;
        }
        let mut segments = Segments::new(self, ray, a.medium, dist)
            .lead(lead_a)
            .open_end(dist + lead_b)
            .from_camera(camera);
        if shortcut && camera {
            if self.occluded_from(&ray, dist, camera) {
                return zero;
            }
            segments = segments.boundaries_only();
        } else if shortcut {
            segments = match self.passage(&ray, dist) {
                Passage::Blocked => return zero,
                Passage::Crossing => segments.boundaries_only(),
                Passage::Clear => segments.clear_ahead(),
            };
        }
        for seg in segments {
            let last = matches!(seg.end, SegmentEnd::Open);
            if let Some(m) = seg.medium {
                let med = &self.media[m as usize];
                let len = seg.t1 - seg.t0;
                let sr = Ray::new(ray.at(seg.t0), d);
                out.transmittance *= tau(med, &sr, len);
                // both directions from one optical depth (`Medium::free_flight_pdfs`)
                let (ab, ba) =
                    med.free_flight_pdfs(&sr, len, last && b_in_medium, seg.first && a_in_medium);
                out.pdf_ab *= ab;
                out.pdf_ba *= ba;
            }
            match seg.end {
                SegmentEnd::Null(_) => {}
                SegmentEnd::Open => return out,
                SegmentEnd::Surface(_) => return zero,
            }
        }
        zero
    }
    // ANCHOR_END: edge

    /// The medium containing `p`: found from the first medium boundary a fixed ray from `p`
    /// meets (leaving through a boundary means being inside it).
    /// The medium light `l`'s paths start in, from its primitive `prim` (an area light's;
    /// `None` for the others): [`Scene::light_prim_media`] where the light's primitives
    /// differ, [`Scene::light_media`] elsewhere.
    #[inline]
    pub fn light_medium(&self, l: usize, prim: Option<u32>) -> Option<u32> {
        if let (Some(media), Some(prim), Light::Area { prims, .. }) =
            (&self.light_prim_media[l], prim, &self.lights[l])
        {
            // an area light's primitives are consecutive (`scene::build::shapes`)
            return media[(prim - prims[0]) as usize];
        }
        self.light_media[l]
    }

    pub fn medium_at(&self, p: Vec3) -> Option<u32> {
        // an irrational-looking direction avoids grazing axis-aligned faces and edges; only
        // medium boundaries count (a wall coplanar with a boundary must not hide it), so this
        // scans the primitives of interface shapes directly: it runs once per light, camera and
        // meter, never per sample
        let d = Vec3::new(0.389_312, 0.727_003, 0.565_516).normalize();
        let ray = Ray::new(p, d);
        let mut best: Option<(f32, Vec3, u32)> = None;
        for (i, prim) in self.prims.iter().enumerate() {
            let shape = self.prim_shape[i];
            if !self.shapes[shape as usize].interface {
                continue;
            }
            let limit = best.map_or(f32::INFINITY, |b| b.0);
            if let Some((t, _, ng)) = prim.intersect(&ray, limit) {
                best = Some((t, ng, shape));
            }
        }
        let (_, ng, shape) = best?;
        let shape = &self.shapes[shape as usize];
        if d.dot(ng) > 0.0 {
            shape.interior
        } else {
            shape.exterior
        }
    }

    /// The selection probability of light `l`.
    #[inline]
    pub fn light_pmf(&self, l: u32) -> f32 {
        self.light_distr.pmf(l as usize)
    }

    /// The position density (per area) of point `prim` of area light `light` (selection of the
    /// primitive by area, then uniform), without the light's selection probability.
    pub fn area_pdf_of(&self, light: u32, prim: u32) -> f32 {
        match &self.lights[light as usize] {
            Light::Area { prims, distr, .. } => match prims.iter().position(|&q| q == prim) {
                Some(k) => distr.pmf(k) / self.prims[prim as usize].area(),
                None => 0.0,
            },
            _ => 0.0,
        }
    }

    /// Loads, validates and builds a scene.
    pub fn load(source: &SceneSource) -> Result<Scene, SceneError> {
        build::build(source)
    }

    /// Sets the propagation strategy of every inhomogeneous medium (for comparing strategies
    /// on one scene, `pathspace converge --propagation`); returns how many media changed.
    pub fn set_line_integral(&mut self, li: crate::medium::heterogeneous::LineIntegral) -> usize {
        self.media
            .iter_mut()
            .map(|m| m.set_line_integral(li))
            .filter(|&set| set)
            .count()
    }

    /// Sets the transmittance estimator of every inhomogeneous medium (`[render]
    /// transmittance`); returns how many media changed.
    pub fn set_transmittance_estimator(
        &mut self,
        e: crate::medium::heterogeneous::TransmittanceEstimator,
    ) -> usize {
        self.media
            .iter_mut()
            .map(|m| m.set_transmittance_estimator(e))
            .filter(|&set| set)
            .count()
    }

    /// The embedded fog box.
    pub fn fog_box() -> Scene {
        Scene::load(&SceneSource::embedded("fog-box.toml (embedded)", FOG_BOX))
            .expect("the embedded fog box is valid (checked by a test)")
    }
}

/// One step of [`Scene::next_flight`].
enum Flight {
    /// The flight collided at `ff.t` past ray parameter `t0` in `medium`, before any surface.
    Collided {
        t0: f32,
        medium: u32,
        /// Whether the segment starts at the ray's origin.
        first: bool,
        ff: FreeFlight,
    },
    /// The ray's next segment and its flight (`None` in vacuum).
    Segment(Segment, Option<FreeFlight>),
    /// More null crossings than [`segments::MAX_NULL_CROSSINGS`].
    Trapped,
}

/// A segment's free flight with its exact transmittance and pdf.
#[inline]
fn full(med: &Medium, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> FreeFlight {
    med.sample_free_flight(ray, t_max, sampler)
}

/// A segment's free flight whose transmittance and pdf may share a factor
/// ([`Medium::sample_free_flight_weight`]).
#[inline]
fn weight(med: &Medium, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> FreeFlight {
    med.sample_free_flight_weight(ray, t_max, sampler).scaled()
}

/// The propagation that ends in a collision `ff` on the segment of `ray` starting at ray
/// parameter `t0` in medium `m`, after the walk's products (transmittance, pdf) so far.
#[inline]
fn collided(
    ray: Ray,
    t0: f32,
    m: u32,
    ff: FreeFlight,
    (transmittance, pdf): (Rgb, f32),
) -> Propagation {
    let sr = Ray::new(ray.at(t0), ray.d);
    Propagation {
        event: Event::Medium {
            p: sr.at(ff.t),
            t: t0 + ff.t,
            medium: m,
            sigma_s: ff.sigma_s,
        },
        transmittance,
        pdf,
        pdf_rev: 1.0,
    }
}

/// The event that ends the walk at the end of a segment the ray passed (`None` at a null
/// boundary, where the walk goes on).
#[inline]
fn segment_event(seg: &Segment) -> Option<Event> {
    match seg.end {
        SegmentEnd::Null(_) => None,
        SegmentEnd::Open => Some(Event::Escape),
        SegmentEnd::Surface(hit) => Some(Event::Surface {
            hit,
            medium: seg.medium,
        }),
    }
}
