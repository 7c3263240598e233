//! Light sources: the emission L_e of eq. (2) on surfaces (area lights), and delta and infinite
//! lights (point, spot, directional, environment).
//!
//! Sampling records carry values and densities separately: `sample_li` (a direction towards
//! the light from a reference point, with its solid-angle pdf) for next-event estimation, and
//! `sample_le` (an emitted ray with position and direction pdfs) for light paths.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use super::{EnvMap, UvMap};
use crate::geometry::Primitive;
use crate::math::spherical::SphericalParallelogram;
use crate::math::{warp, Distribution1D, Frame};
use crate::spectrum::Rgb;
use crate::texture::Texture;

/// What an area light emits from a point of its surface (Mitsuba 3 documentation, plugin
/// `area`: `radiance` is a spectrum or a texture over the shape's (u, v)).
#[derive(Clone, Debug)]
pub enum AreaRadiance {
    Constant(Rgb),
    /// The texture looked up at the point's (u, v) by `uv`, the shape's map (as a textured
    /// reflectance); `mean`, its mean over the unit square, stands in for it in the light's
    /// power, which only weighs the light's selection (points stay uniform by area).
    Textured {
        texture: std::sync::Arc<Texture>,
        uv: UvMap,
        mean: Rgb,
    },
}

impl AreaRadiance {
    /// The radiance at the scene's primitive `prim`'s point `p`: the one place an area light's
    /// radiance is read (its (u, v) computed only when textured).
    #[inline]
    pub fn at(&self, prims: &[Primitive], prim: u32, p: Vec3) -> Rgb {
        match self {
            AreaRadiance::Constant(l) => *l,
            AreaRadiance::Textured { texture, uv, .. } => texture.eval(uv.uv_of(prims, prim, p)),
        }
    }

    /// The mean radiance over the surface's (u, v) (the constant itself).
    pub fn mean(&self) -> Rgb {
        match self {
            AreaRadiance::Constant(l) => *l,
            AreaRadiance::Textured { mean, .. } => *mean,
        }
    }
}

/// A constant, vertical gradient or image-based environment: radiance as a function of
/// direction.
#[derive(Clone, Debug, PartialEq)]
pub enum Environment {
    Constant(Rgb),
    /// Linear in the y component of the direction the light comes from: `horizon` at y = 0,
    /// `zenith` at y = 1, `nadir` at y = -1.
    Gradient {
        zenith: Rgb,
        horizon: Rgb,
        nadir: Rgb,
    },
    /// A latitude-longitude map, sampled by luminance ([`EnvMap`]).
    Map(Box<EnvMap>),
}

impl Environment {
    /// Radiance arriving from direction `w` (pointing away from the scene, towards the sky).
    #[inline]
    pub fn radiance(&self, w: Vec3) -> Rgb {
        match self {
            Environment::Constant(l) => *l,
            Environment::Gradient {
                zenith,
                horizon,
                nadir,
            } => {
                if w.y >= 0.0 {
                    horizon.lerp(*zenith, w.y)
                } else {
                    horizon.lerp(*nadir, -w.y)
                }
            }
            Environment::Map(map) => map.radiance(w),
        }
    }

    /// A direction `w` towards the sky from `u`, its radiance and its solid-angle density:
    /// uniform on the sphere, or by the map's luminance.
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        match self {
            Environment::Map(map) => map.sample(u),
            _ => {
                let w = warp::uniform_sphere(u);
                Some((w, self.radiance(w), warp::INV_FOUR_PI))
            }
        }
    }

    /// The solid-angle density of [`Environment::sample`] drawing `w`.
    #[inline]
    pub fn pdf(&self, w: Vec3) -> f32 {
        match self {
            Environment::Map(map) => map.pdf(w),
            _ => warp::INV_FOUR_PI,
        }
    }

    /// Total power proxy: the mean radiance over the sphere.
    pub fn mean_radiance(&self) -> Rgb {
        match self {
            Environment::Constant(l) => *l,
            Environment::Gradient {
                zenith,
                horizon,
                nadir,
            } => {
                // the mean of a function linear in y over each hemisphere is its value at y = 1/2
                0.5 * (horizon.lerp(*zenith, 0.5) + horizon.lerp(*nadir, 0.5))
            }
            Environment::Map(map) => map.mean_radiance(),
        }
    }
}

/// The closed set of light types.
#[derive(Clone, Debug)]
pub enum Light {
    /// Emission `radiance` from the normal side of the primitives `prims` (one shape).
    Area {
        shape: u32,
        prims: Vec<u32>,
        /// Selection of a primitive proportional to its area.
        distr: Distribution1D,
        area: f32,
        radiance: AreaRadiance,
    },
    Point {
        position: Vec3,
        intensity: Rgb,
    },
    Spot {
        position: Vec3,
        frame: Frame,
        intensity: Rgb,
        cos_total: f32,
        cos_falloff: f32,
    },
    /// Collimated light travelling along `direction`.
    Directional {
        direction: Vec3,
        irradiance: Rgb,
    },
    Environment(Environment),
}

/// A direction towards a light from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the reference point towards the light.
    pub wi: Vec3,
    /// Distance to the sampled point (infinite for directional and environment lights).
    pub dist: f32,
    /// The point on the light (for finite lights) and its normal (zero for delta lights).
    pub p: Vec3,
    pub n: Vec3,
    /// Emitted radiance towards the reference point, or intensity / irradiance for delta lights.
    pub value: Rgb,
    /// Solid-angle density at the reference point of this light's sampling routine (the light
    /// selection probability is not included); 1 for delta lights.
    pub pdf: f32,
    pub is_delta: bool,
}

/// How next-event estimation draws the point of an area light it aims at.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LightPointDraw {
    /// Uniform by area on a primitive chosen by area: the density light subpaths start
    /// with, which bidirectional weights compare against, and the one that equiangular
    /// sampling's distance weights assume.
    Area,
    /// Uniform by solid angle over a quad or triangle whose centre is near the reference point
    /// ([`NEAR_AREA_FACTOR`]), by area elsewhere. Seen from near, area sampling's estimate
    /// grows as 1 / r^2, and MIS hands it to the phase or BSDF sample, a hit or miss; drawn by
    /// solid angle it is the primitive's solid angle times L_e, whatever point is drawn.
    #[default]
    SolidAngleNear,
}

crate::option_value!(LightPointDraw, "light point");

/// A quad or a triangle is drawn by solid angle from points whose squared distance to its
/// centre is at most this many times its area (within one side of a square's centre): nearly
/// all of the variance that area sampling adds is there (the fog box's path tracer: 0.59 of its
/// error per sample at 1.01 of its cost), and farther out the spherical construction costs
/// more than it saves.
pub const NEAR_AREA_FACTOR: f32 = 1.0;

/// The quad or triangle `prim` as seen from `x`, and its normal, when
/// [`LightPointDraw::SolidAngleNear`] draws it by solid angle there: `x` near it, in front of
/// its emitting side.
fn near_view(prim: &Primitive, x: Vec3) -> Option<(SphericalParallelogram, Vec3)> {
    let (corner, centre, n) = match prim {
        Primitive::Quad(q) => (q.origin, q.origin + 0.5 * (q.u + q.v), q.n),
        Primitive::Triangle(t) => (t.p0, (t.p0 + t.p1 + t.p2) / 3.0, t.n),
        _ => return None,
    };
    if (centre - x).length_squared() > NEAR_AREA_FACTOR * prim.area() || (x - corner).dot(n) <= 0.0
    {
        return None;
    }
    let view = match prim {
        Primitive::Quad(q) => SphericalParallelogram::new(x, q.origin, q.u, q.v),
        Primitive::Triangle(t) => SphericalParallelogram::triangle(x, t.p0, t.p1, t.p2),
        _ => None,
    };
    Some((view?, n))
}

/// A point drawn on a finite light ([`Light::sample_point`]).
#[derive(Clone, Copy, Debug)]
pub struct LightPoint {
    pub p: Vec3,
    /// Its unit normal (zero for point and spot lights).
    pub n: Vec3,
    /// Its density per area (1 for point and spot lights).
    pub pdf_area: f32,
    /// The scene's primitive it lies on (an area light's; 0 otherwise).
    pub prim: u32,
}

/// An emitted ray for light paths.
#[derive(Clone, Copy, Debug)]
pub struct EmissionSample {
    pub p: Vec3,
    /// Unit geometric normal at `p` (zero for point and spot lights; the direction for
    /// directional and environment lights).
    pub n: Vec3,
    /// Unit direction of emission.
    pub d: Vec3,
    /// Emitted radiance (area, environment), intensity (point, spot) or irradiance (directional).
    pub value: Rgb,
    /// Density of `p`: per area (area lights; the disk for infinite lights), 1 for point lights.
    pub pdf_pos: f32,
    /// Solid-angle density of `d` (1 for directional light).
    pub pdf_dir: f32,
}

/// Smoothstep falloff of a spot light.
fn spot_falloff(cos: f32, cos_total: f32, cos_falloff: f32) -> f32 {
    if cos < cos_total {
        0.0
    } else if cos >= cos_falloff {
        1.0
    } else {
        let x = (cos - cos_total) / (cos_falloff - cos_total);
        x * x * (3.0 - 2.0 * x)
    }
}

impl Light {
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point { .. } | Light::Spot { .. } | Light::Directional { .. }
        )
    }

    pub fn is_infinite(&self) -> bool {
        matches!(self, Light::Directional { .. } | Light::Environment(_))
    }

    /// Emitted power (for light selection). `scene_radius` bounds infinite lights.
    pub fn power(&self, scene_radius: f32) -> f32 {
        let lum = |c: Rgb| crate::spectrum::average(c);
        match self {
            Light::Area { area, radiance, .. } => PI * area * lum(radiance.mean()),
            Light::Point { intensity, .. } => 4.0 * PI * lum(*intensity),
            Light::Spot {
                intensity,
                cos_total,
                cos_falloff,
                ..
            } => 2.0 * PI * lum(*intensity) * (1.0 - 0.5 * (cos_total + cos_falloff)),
            Light::Directional { irradiance, .. } => {
                PI * scene_radius * scene_radius * lum(*irradiance)
            }
            Light::Environment(env) => {
                4.0 * PI * PI * scene_radius * scene_radius * lum(env.mean_radiance())
            }
        }
    }

    /// A point on a finite light drawn without a reference point: an area light's as
    /// [`Light::sample_li`] draws it (a primitive by area, then uniform on it), a point or spot
    /// light's position (normal zero, density 1); `None` for infinite lights. Equiangular
    /// sampling needs the light point before the point it lights.
    pub fn sample_point(&self, prims: &[Primitive], u: Vec2, u_prim: f32) -> Option<LightPoint> {
        match self {
            Light::Area {
                prims: ids, distr, ..
            } => {
                let (k, pk, _) = distr.sample(u_prim);
                let prim = &prims[ids[k] as usize];
                let (p, n) = prim.sample_area(u);
                // area density pk / A_k
                Some(LightPoint {
                    p,
                    n,
                    pdf_area: pk / prim.area(),
                    prim: ids[k],
                })
            }
            Light::Point { position, .. } | Light::Spot { position, .. } => Some(LightPoint {
                p: *position,
                n: Vec3::ZERO,
                pdf_area: 1.0,
                prim: 0,
            }),
            Light::Directional { .. } | Light::Environment(_) => None,
        }
    }

    /// The light sample from `p_ref` towards the point `at` that [`Light::sample_point`] drew:
    /// what [`Light::sample_li`] returns when it draws that point.
    pub fn li_towards(
        &self,
        prims: &[Primitive],
        p_ref: Vec3,
        at: &LightPoint,
    ) -> Option<LightSample> {
        match self {
            Light::Area { .. } => self.li_from(prims, at.prim, p_ref, at.p, at.n, at.pdf_area),
            // a delta light's sample does not depend on the random numbers
            _ => self.sample_li(prims, p_ref, (Vec2::ZERO, 0.0), LightPointDraw::Area),
        }
    }

    /// An area light's radiance at point `p` of the scene's primitive `prim` (one of its
    /// own); black for other lights ([`AreaRadiance::at`]).
    #[inline]
    pub fn area_radiance(&self, prims: &[Primitive], prim: u32, p: Vec3) -> Rgb {
        match self {
            Light::Area { radiance, .. } => radiance.at(prims, prim, p),
            _ => Rgb::ZERO,
        }
    }

    /// Samples a direction towards the light from `p_ref` (next-event estimation), an area
    /// light's point drawn as `draw` says.
    pub fn sample_li(
        &self,
        prims: &[Primitive],
        p_ref: Vec3,
        (u, u_prim): (Vec2, f32),
        draw: LightPointDraw,
    ) -> Option<LightSample> {
        match self {
            Light::Area {
                prims: ids, distr, ..
            } => {
                if draw == LightPointDraw::SolidAngleNear {
                    let (k, pk, _) = distr.sample(u_prim);
                    let prim = &prims[ids[k] as usize];
                    if let Some((view, n)) = near_view(prim, p_ref) {
                        let s = view.sample(u)?;
                        let ls = self.li_from(prims, ids[k], p_ref, s.p, n, 1.0)?;
                        let pdf = pk * s.pdf_solid_angle;
                        return Some(LightSample { pdf, ..ls });
                    }
                }
                let at = self.sample_point(prims, u, u_prim)?;
                // the back of an emitter is black
                self.li_from(prims, at.prim, p_ref, at.p, at.n, at.pdf_area)
            }
            Light::Point {
                position,
                intensity,
            } => {
                let to = *position - p_ref;
                let d2 = to.length_squared();
                let dist = d2.sqrt();
                if dist <= 0.0 {
                    return None;
                }
                // intensity / d^2 is the irradiance on a surface facing the light
                Some(LightSample {
                    wi: to / dist,
                    dist,
                    p: *position,
                    n: Vec3::ZERO,
                    value: *intensity / d2,
                    pdf: 1.0,
                    is_delta: true,
                })
            }
            Light::Spot {
                position,
                frame,
                intensity,
                cos_total,
                cos_falloff,
            } => {
                let to = *position - p_ref;
                let d2 = to.length_squared();
                let dist = d2.sqrt();
                if dist <= 0.0 {
                    return None;
                }
                let wi = to / dist;
                let f = spot_falloff(-wi.dot(frame.n), *cos_total, *cos_falloff);
                if f <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    dist,
                    p: *position,
                    n: Vec3::ZERO,
                    value: *intensity * f / d2,
                    pdf: 1.0,
                    is_delta: true,
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                wi: -*direction,
                dist: f32::INFINITY,
                p: Vec3::ZERO,
                n: *direction,
                value: *irradiance,
                pdf: 1.0,
                is_delta: true,
            }),
            Light::Environment(env) => {
                let (wi, value, pdf) = env.sample(u)?;
                Some(LightSample {
                    wi,
                    dist: f32::INFINITY,
                    p: Vec3::ZERO,
                    n: -wi,
                    value,
                    pdf,
                    is_delta: false,
                })
            }
        }
    }

    /// Solid-angle density of [`Light::sample_li`] (drawing as `draw` says) producing the
    /// point `p` (normal `n`) of primitive `prim` of this area light from `p_ref`, or
    /// direction `wi = -n` for the environment (its [`LightSample::n`]).
    pub fn pdf_li(
        &self,
        prims: &[Primitive],
        p_ref: Vec3,
        (p, n, prim): (Vec3, Vec3, u32),
        draw: LightPointDraw,
    ) -> f32 {
        match self {
            Light::Area {
                prims: ids, distr, ..
            } => {
                let Some(k) = ids.iter().position(|&i| i == prim) else {
                    return 0.0;
                };
                let to = p - p_ref;
                let d2 = to.length_squared();
                let cos_l = -(to / d2.sqrt()).dot(n);
                if cos_l <= 0.0 {
                    return 0.0;
                }
                let shape = &prims[prim as usize];
                if draw == LightPointDraw::SolidAngleNear {
                    if let Some((view, _)) = near_view(shape, p_ref) {
                        return distr.pmf(k) / view.solid_angle() as f32;
                    }
                }
                distr.pmf(k) / shape.area() * d2 / cos_l
            }
            Light::Environment(env) => env.pdf(-n),
            _ => 0.0,
        }
    }

    /// The emitted ray of an area light from a given point `p` of primitive `prim` (normal
    /// `n`, position density `pdf_pos`): a cosine-distributed direction from `u_dir`, as
    /// [`Light::sample_le`] draws it. Used when the position comes from elsewhere (the adjoint
    /// image).
    pub fn emission_at(
        &self,
        prims: &[Primitive],
        prim: u32,
        (p, n): (Vec3, Vec3),
        pdf_pos: f32,
        u_dir: Vec2,
    ) -> EmissionSample {
        let local = warp::cosine_hemisphere(u_dir);
        let d = Frame::from_normal(n).to_world(local);
        let value = self.area_radiance(prims, prim, p);
        EmissionSample {
            p,
            n,
            d,
            value,
            pdf_pos,
            pdf_dir: warp::cosine_hemisphere_pdf(local),
        }
    }

    /// A [`LightSample`] towards point `p` (normal `n`) of primitive `prim` of this area light
    /// from `p_ref`, the point having been drawn elsewhere with area density `pdf_area`; `pdf`
    /// is converted to solid angle at `p_ref`. `None` from behind the emitter or at zero
    /// distance.
    pub fn li_from(
        &self,
        prims: &[Primitive],
        prim: u32,
        p_ref: Vec3,
        p: Vec3,
        n: Vec3,
        pdf_area: f32,
    ) -> Option<LightSample> {
        let Light::Area { radiance, .. } = self else {
            return None;
        };
        let to = p - p_ref;
        let d2 = to.length_squared();
        if d2 <= 0.0 {
            return None;
        }
        let dist = d2.sqrt();
        let wi = to / dist;
        let cos_l = -wi.dot(n);
        if cos_l <= 0.0 {
            return None;
        }
        Some(LightSample {
            wi,
            dist,
            p,
            n,
            value: radiance.at(prims, prim, p),
            pdf: pdf_area * d2 / cos_l,
            is_delta: false,
        })
    }

    /// Samples an emitted ray (for light paths). `center`, `radius` bound the scene.
    pub fn sample_le(
        &self,
        prims: &[Primitive],
        u_pos: Vec2,
        u_dir: Vec2,
        u_prim: f32,
        center: Vec3,
        radius: f32,
    ) -> Option<EmissionSample> {
        match self {
            Light::Area {
                prims: ids,
                distr,
                radiance,
                ..
            } => {
                let (k, pk, _) = distr.sample(u_prim);
                let prim = &prims[ids[k] as usize];
                let (p, n) = prim.sample_area(u_pos);
                let local = warp::cosine_hemisphere(u_dir);
                let d = Frame::from_normal(n).to_world(local);
                Some(EmissionSample {
                    p,
                    n,
                    d,
                    value: radiance.at(prims, ids[k], p),
                    pdf_pos: pk / prim.area(),
                    pdf_dir: warp::cosine_hemisphere_pdf(local),
                })
            }
            Light::Point {
                position,
                intensity,
            } => Some(EmissionSample {
                p: *position,
                n: Vec3::ZERO,
                d: warp::uniform_sphere(u_dir),
                value: *intensity,
                pdf_pos: 1.0,
                pdf_dir: warp::INV_FOUR_PI,
            }),
            Light::Spot {
                position,
                frame,
                intensity,
                cos_total,
                cos_falloff,
            } => {
                let local = warp::uniform_cone(u_dir, *cos_total);
                let d = frame.to_world(local);
                Some(EmissionSample {
                    p: *position,
                    n: Vec3::ZERO,
                    d,
                    value: *intensity * spot_falloff(local.z, *cos_total, *cos_falloff),
                    pdf_pos: 1.0,
                    pdf_dir: 1.0 / (2.0 * PI * (1.0 - cos_total)),
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                // a disk of the scene's radius facing the light, outside the scene
                let frame = Frame::from_normal(*direction);
                let disk = warp::concentric_disk(u_pos) * radius;
                let p = center - *direction * radius + frame.s * disk.x + frame.t * disk.y;
                Some(EmissionSample {
                    p,
                    n: *direction,
                    d: *direction,
                    value: *irradiance,
                    pdf_pos: 1.0 / (PI * radius * radius),
                    pdf_dir: 1.0,
                })
            }
            Light::Environment(env) => {
                let (w, value, pdf_dir) = env.sample(u_dir)?;
                let d = -w;
                let frame = Frame::from_normal(d);
                let disk = warp::concentric_disk(u_pos) * radius;
                let p = center + w * radius + frame.s * disk.x + frame.t * disk.y;
                Some(EmissionSample {
                    p,
                    n: d,
                    d,
                    value,
                    pdf_pos: 1.0 / (PI * radius * radius),
                    pdf_dir,
                })
            }
        }
    }
}

/// Emitted radiance (or intensity, irradiance) of `light` in direction `w` from a point `p`
/// with normal `n` (on the scene's primitive `prim` of an area light).
pub fn emitted_by(
    light: &Light,
    prims: &[Primitive],
    prim: u32,
    (p, n): (Vec3, Vec3),
    w: Vec3,
) -> Rgb {
    match light {
        Light::Area { radiance, .. } => {
            if n.dot(w) > 0.0 {
                radiance.at(prims, prim, p)
            } else {
                Rgb::ZERO
            }
        }
        Light::Point { intensity, .. } => *intensity,
        Light::Spot {
            frame,
            intensity,
            cos_total,
            cos_falloff,
            ..
        } => {
            let c = w.dot(frame.n);
            if c < *cos_total {
                Rgb::ZERO
            } else if c >= *cos_falloff {
                *intensity
            } else {
                let x = (c - cos_total) / (cos_falloff - cos_total);
                *intensity * (x * x * (3.0 - 2.0 * x))
            }
        }
        Light::Directional { irradiance, .. } => *irradiance,
        // an infinite light's vertex sits far out along -w: radiance arriving along w... the
        // light comes from direction -w as seen from the scene
        Light::Environment(env) => env.radiance(-w),
    }
}

/// Solid-angle density of the emission direction `w` of `light` at a point with normal `n`.
pub fn emission_pdf_dir(light: &Light, n: Vec3, w: Vec3) -> f32 {
    match light {
        Light::Area { .. } => n.dot(w).max(0.0) * std::f32::consts::FRAC_1_PI,
        Light::Point { .. } => warp::INV_FOUR_PI,
        Light::Spot {
            frame, cos_total, ..
        } => {
            if w.dot(frame.n) >= *cos_total {
                1.0 / (2.0 * std::f32::consts::PI * (1.0 - cos_total))
            } else {
                0.0
            }
        }
        Light::Directional { .. } => 0.0,
        Light::Environment(env) => env.pdf(-w),
    }
}
