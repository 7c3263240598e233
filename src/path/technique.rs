//! The local-sampling technique (Pauly, Kollig, Keller 2000, sec. 4: how each vertex of a path
//! is sampled): where a light path starts, which direction a light emits, which direction a
//! surface or medium vertex scatters in, which lobe glass takes and whether roulette ends the
//! walk, each with the density it samples by.
//!
//! Every walk, every MIS weight ([`crate::path::Vertex::pdf_dir`], [`crate::path::pdf`]), MLT's
//! mutations and their transition densities and the particle samplers receive one
//! [`LocalSampling`] and ask it both for samples and for densities, so a method evaluates the
//! density it sampled with by construction. [`Plain`] samples by power, BSDF and phase
//! function; the enlightened technique (`enlightened::Enlightened`: guided mixtures and the
//! adjoint image, Kristensen 2010 ch. 5) implements the same interface one layer up.
//! Book: "Path space (eqs. 5-7)" and "Enlightened local path sampling".

use glam::{Vec2, Vec3};

use super::geometry_term::{cosine_factor, to_area};
use super::{Vertex, VertexKind};
use crate::bsdf::{BsdfSample, Lobe, TransportMode};
use crate::math::Sampler;
use crate::medium::phase::PhaseSample;
use crate::scene::light::EmissionSample;
use crate::scene::{Light, Scene};
use crate::spectrum::Rgb;
use std::f32::consts::FRAC_1_PI;

/// A point F(u) on an area light (the light-sampling map of Kristensen 2010, sec. 5.2.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapPoint {
    pub light: u32,
    pub prim: u32,
    pub p: Vec3,
    pub n: Vec3,
}

/// A light start point a technique drew by its own density instead of by power (the adjoint
/// image, Kristensen 2010 sec. 5.3.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightStart {
    pub point: MapPoint,
    /// Area density of the point, the light selection included:
    /// P(area lights) P_j N_cells p_F(x_0).
    pub pdf: f32,
}

/// How a technique starts a light path on the light chosen by power: by the light's own
/// (power and area) density, or at a point of its own, or not at all (its pick failed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StartDraw {
    /// The light's own position sampling (`Light::sample_le`, `Light::sample_li`).
    ByPower,
    /// A start point drawn by the technique, with its density.
    Drawn(LightStart),
    /// The technique's pick failed: the sample ends.
    Failed,
}

/// A sampled scattering direction: f (f_s at surfaces, f_p in the medium, sigma_s not
/// included), the density it was drawn with, the lobe, and the guided roulette's estimate
/// Lhat(wi) (`None` where no map guides the vertex).
#[derive(Clone, Copy, Debug)]
pub struct ScatterSample {
    pub wi: Vec3,
    pub value: Rgb,
    pub pdf: f32,
    pub lobe: Lobe,
    pub lhat: Option<f32>,
}

impl ScatterSample {
    /// A BSDF's own sample, unguided.
    pub fn from_bsdf(bs: BsdfSample) -> Self {
        ScatterSample {
            wi: bs.wi,
            value: bs.value,
            pdf: bs.pdf,
            lobe: bs.lobe,
            lhat: None,
        }
    }

    /// A phase function's own sample, unguided.
    pub fn from_phase(ps: PhaseSample) -> Self {
        ScatterSample {
            wi: ps.wi,
            value: Rgb::splat(ps.value),
            pdf: ps.pdf,
            lobe: Lobe::Regular,
            lhat: None,
        }
    }

    /// As a BSDF sample (for code that multiplies by value |cos| / pdf).
    pub fn as_bsdf_sample(&self) -> BsdfSample {
        BsdfSample {
            wi: self.wi,
            value: self.value,
            pdf: self.pdf,
            lobe: self.lobe,
        }
    }
}

/// The lobe choice at a glass vertex: P(reflect), the reflection sample and the transmission
/// sample (`None` under total internal reflection).
pub type LobeChoice = (f32, BsdfSample, Option<BsdfSample>);

/// A local-sampling technique: the one place that samples a vertex and evaluates the density
/// it sampled with (Pauly et al. 2000, sec. 4). Passed explicitly to every walk and density,
/// because BDPT's MIS, `path::pdf::densities` and MLT's transition densities must see the
/// density the walk used.
pub trait LocalSampling: Sync + std::fmt::Debug {
    /// The start of a light path on light `light` (chosen by power) with position numbers
    /// `u_pos`; a technique of its own start density draws any further numbers from `sampler`.
    fn sample_light_start(
        &self,
        scene: &Scene,
        light: usize,
        u_pos: Vec2,
        sampler: &mut Sampler,
    ) -> StartDraw;

    /// The light-start density (per area, light selection included) of point `p` on primitive
    /// `prim` of area light `light`.
    fn area_light_start_pdf(&self, scene: &Scene, light: u32, prim: u32, p: Vec3) -> f32;

    /// Whether emission directions of `light` come from the technique rather than from the
    /// light's own sampler (then [`LocalSampling::sample_emission`] replaces them).
    fn guides_emission(&self, light: &Light) -> bool;

    /// The emission direction at light point (p, n) of `light`, given the direction `d_le`
    /// the light drew with numbers `u`: the direction and its density.
    fn sample_emission(
        &self,
        scene: &Scene,
        light: &Light,
        at: (Vec3, Vec3),
        d_le: Vec3,
        u: Vec2,
        sampler: &mut Sampler,
    ) -> Option<(Vec3, f32)>;

    /// The solid-angle density of emission direction `w` from point (p, n) of `light`.
    fn emission_pdf(&self, scene: &Scene, light: &Light, p: Vec3, n: Vec3, w: Vec3) -> f32;

    /// Samples a scattering direction at surface or medium vertex `v` of a `mode` subpath
    /// reached from `wo`, with the first two numbers `u` already drawn.
    fn sample_scatter_with(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        mode: TransportMode,
        u: Vec2,
        sampler: &mut Sampler,
    ) -> Option<ScatterSample>;

    /// The solid-angle density with which [`LocalSampling::sample_scatter_with`] draws `wi`.
    fn scatter_pdf(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        wi: Vec3,
        mode: TransportMode,
    ) -> f32;

    /// The technique's own lobe choice at a glass vertex (`None`: the BSDF's Fresnel choice).
    fn lobe_choice(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        mode: TransportMode,
    ) -> Option<LobeChoice>;

    /// The technique's own roulette survival probability (`None`: the throughput rule).
    fn roulette_survival(
        &self,
        lhat: Option<f32>,
        throughput_ratio: f32,
        q_max: f32,
    ) -> Option<f32>;

    /// Whether the technique guides any scattering direction (its [`LocalSampling::sample_scatter`]
    /// differs from the BSDF's and phase function's own): the path tracer, which otherwise
    /// samples them itself, then asks the technique.
    fn guides_scattering(&self) -> bool {
        false
    }

    /// [`LocalSampling::sample_scatter_with`] drawing its numbers from `sampler`: a surface
    /// without a BSDF ends the walk before any number is drawn (the streams of plain renders
    /// stay as they always were).
    fn sample_scatter(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        mode: TransportMode,
        sampler: &mut Sampler,
    ) -> Option<ScatterSample> {
        if matches!(v.kind, VertexKind::Surface { .. }) && v.bsdf(scene).is_none() {
            return None;
        }
        let u = sampler.next_2d();
        self.sample_scatter_with(scene, v, wo, mode, u, sampler)
    }
}

/// The number of scattering vertices after which Russian roulette starts. The bidirectional
/// walks count only vertices whose direction was drawn from a lobe with a density: a chain of
/// specular vertices carries its light along one ray, and glass crossed before the first
/// diffuse bounce would otherwise start the roulette there (book: "Surface scattering", the
/// roulette's common mistakes). SMC's walks, through media, count every vertex.
pub const RR_START_DEPTH: u32 = 3;
/// Survival probabilities are capped below one so every path ends with probability one.
pub const RR_MAX_SURVIVAL: f32 = 0.95;

/// The plain technique: lights by power and area, emission by the light's own density, the
/// BSDF's or phase function's own sampling, Fresnel at glass, roulette by throughput.
#[derive(Clone, Copy, Debug, Default)]
pub struct Plain;

/// The plain technique as a value any renderer can borrow for as long as it likes.
pub static PLAIN: Plain = Plain;

/// The BSDF's or phase function's own density of `wi` at `v` (`None` at a surface without a
/// BSDF or a vertex that does not scatter): the local part of every technique's density.
#[inline]
pub fn local_scatter_pdf(scene: &Scene, v: &Vertex, wo: Vec3, wi: Vec3) -> Option<f32> {
    match v.kind {
        VertexKind::Surface { .. } => v.bsdf(scene).map(|b| b.pdf_shaded(wo, wi, v.normals())),
        VertexKind::Medium { medium } => Some(scene.media[medium as usize].phase().pdf(wo, wi)),
        _ => None,
    }
}

/// The power-and-area light-start density of point `prim` of area light `light`.
#[inline]
pub fn power_light_start_pdf(scene: &Scene, light: u32, prim: u32) -> f32 {
    scene.light_pmf(light) * scene.area_pdf_of(light, prim)
}

impl LocalSampling for Plain {
    fn sample_light_start(&self, _: &Scene, _: usize, _: Vec2, _: &mut Sampler) -> StartDraw {
        StartDraw::ByPower
    }

    #[inline]
    fn area_light_start_pdf(&self, scene: &Scene, light: u32, prim: u32, _p: Vec3) -> f32 {
        power_light_start_pdf(scene, light, prim)
    }

    fn guides_emission(&self, _: &Light) -> bool {
        false
    }

    fn sample_emission(
        &self,
        _: &Scene,
        light: &Light,
        (_, n): (Vec3, Vec3),
        d_le: Vec3,
        _u: Vec2,
        _: &mut Sampler,
    ) -> Option<(Vec3, f32)> {
        Some((d_le, crate::scene::light::emission_pdf_dir(light, n, d_le)))
    }

    fn emission_pdf(&self, _: &Scene, light: &Light, _p: Vec3, n: Vec3, w: Vec3) -> f32 {
        crate::scene::light::emission_pdf_dir(light, n, w)
    }

    fn sample_scatter_with(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        mode: TransportMode,
        u: Vec2,
        sampler: &mut Sampler,
    ) -> Option<ScatterSample> {
        match v.kind {
            VertexKind::Surface { .. } => {
                let uc = sampler.next_f32();
                let bsdf = v.bsdf(scene)?;
                bsdf.sample_shaded(wo, v.normals(), u, uc, mode)
                    .map(ScatterSample::from_bsdf)
            }
            VertexKind::Medium { medium } => Some(ScatterSample::from_phase(
                scene.media[medium as usize].phase().sample(wo, u),
            )),
            _ => None,
        }
    }

    fn scatter_pdf(&self, scene: &Scene, v: &Vertex, wo: Vec3, wi: Vec3, _: TransportMode) -> f32 {
        local_scatter_pdf(scene, v, wo, wi).unwrap_or(0.0)
    }

    fn lobe_choice(&self, _: &Scene, _: &Vertex, _: Vec3, _: TransportMode) -> Option<LobeChoice> {
        None
    }

    fn roulette_survival(&self, _: Option<f32>, _: f32, _: f32) -> Option<f32> {
        None
    }
}

/// A light path's start: the light chosen by power (`pmf`), the emitted ray the light or the
/// technique drew, the density of its start point with the selection included, and the
/// primitive of an area light's point, with the direction numbers the light used (a guided
/// emission reuses them).
#[derive(Clone, Copy, Debug)]
pub struct EmittedStart {
    pub light: usize,
    pub pmf: f32,
    pub es: EmissionSample,
    pub start_pdf: f32,
    pub prim: Option<u32>,
    pub u_dir: Vec2,
}

/// The start of a light subpath, written once for every sampler of one (BDPT's and light
/// tracing's light subpaths, MLT's bidirectional mutation, the particle tracers): a light by
/// power, then its start point from the technique or by the light's power and area, and an
/// emission direction from the light. `None` when a sampler fails.
// ANCHOR: sample_emitted_start
pub fn sample_emitted_start(
    tech: &dyn LocalSampling,
    scene: &Scene,
    sampler: &mut Sampler,
) -> Option<EmittedStart> {
    let (mut l, pmf, u_prim) = scene.light_distr.sample(sampler.next_f32());
    let u_pos = sampler.next_2d();
    let u_dir = sampler.next_2d();
    let (es, start_pdf, prim) = match tech.sample_light_start(scene, l, u_pos, sampler) {
        StartDraw::Failed => return None,
        StartDraw::Drawn(st) => {
            l = st.point.light as usize;
            let at = (st.point.p, st.point.n);
            let es = scene.lights[l].emission_at(&scene.prims, st.point.prim, at, st.pdf, u_dir);
            (es, st.pdf, Some(st.point.prim))
        }
        StartDraw::ByPower => {
            let light = &scene.lights[l];
            let es = light.sample_le(
                &scene.prims,
                u_pos,
                u_dir,
                u_prim,
                scene.center,
                scene.radius,
            )?;
            let prim = match light {
                Light::Area { prims, distr, .. } => Some(prims[distr.sample(u_prim).0]),
                _ => None,
            };
            (es, pmf * es.pdf_pos, prim)
        }
    };
    Some(EmittedStart {
        light: l,
        pmf,
        es,
        start_pdf,
        prim,
        u_dir,
    })
}
// ANCHOR_END: sample_emitted_start

/// A vertex's densities under a local-sampling technique: the direction it samples towards the
/// next vertex (solid angle, or converted to the next vertex's measure), and, for a light
/// path's start, the density of choosing it and of the direction it emits along.
impl Vertex {
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
                .and_then(|c| c.importance(self.p, wn))
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
