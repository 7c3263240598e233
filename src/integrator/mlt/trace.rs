//! Building path vertices for mutations: sampling a direction at a vertex and propagating to the
//! next one with a sampled free-flight distance (the local sampling of the bidirectional
//! mutation, Pauly et al. sec. 4), and the deterministic retracing the perturbations need (sec.
//! 5.2: "retracing the original path with the same scattering interaction types" and the same
//! characteristic): rays cast to the first non-null surface without collisions, medium vertices
//! placed at a given distance, specular vertices continued in their old lobe.

use glam::{Vec2, Vec3};

use crate::bsdf::{Lobe, TransportMode};
use crate::geometry::{offset_origin, Ray};
use crate::math::{warp, Frame, Sampler};
use crate::path::{LocalSampling, Vertex, VertexKind};
use crate::scene::{Event, Light, Scene, SegmentEnd, Segments};

use super::contribution::{infinite_distance, singular_bsdf, specular_sample};

/// The ray leaving vertex `v` along unit `d`: its origin (lifted off surfaces), the distance
/// between the vertex and that origin, and the medium it starts in.
pub fn ray_from(scene: &Scene, v: &Vertex, d: Vec3) -> (Ray, f32, Option<u32>) {
    match v.kind {
        VertexKind::Surface { .. } | VertexKind::Light { prim: Some(_), .. } => {
            let o = offset_origin(v.p, v.n, d);
            (
                Ray::new(o, d),
                (o - v.p).dot(d).max(0.0),
                v.medium_towards(d),
            )
        }
        VertexKind::Camera => (Ray::new(v.p, d), 0.0, scene.camera_medium),
        _ => (Ray::new(v.p, d), 0.0, v.medium_front),
    }
}

/// The medium segments of `ray` leaving `v`: seen from the camera when `v` is it (hidden
/// emitters transparent, [`Segments::from_camera`]).
fn segments_from<'a>(scene: &'a Scene, v: &Vertex, ray: Ray, medium: Option<u32>) -> Segments<'a> {
    Segments::new(scene, ray, medium, f32::INFINITY).from_camera(v.is_camera())
}

/// Samples a direction at `v` as a light or eye subpath would: emission for a light vertex,
/// a uniform film position seen from the camera vertex's lens point (a thin lens's rays pass
/// through the film point's image on the focus plane), the BSDF or phase function elsewhere
/// (`prev` is the subpath predecessor).
pub fn sample_direction(
    scene: &Scene,
    tech: &dyn LocalSampling,
    prev: Option<&Vertex>,
    v: &Vertex,
    mode: TransportMode,
    sampler: &mut Sampler,
) -> Option<Vec3> {
    let u = sampler.next_2d();
    match v.kind {
        VertexKind::Camera => {
            let cam = scene.camera.as_ref()?;
            let raster = Vec2::new(u.x * cam.width as f32, u.y * cam.height as f32);
            // from the vertex's lens point (the pinhole ignores it: `generate_ray`)
            Some(cam.ray_through(raster, v.p).d)
        }
        VertexKind::Light { light, .. } => match &scene.lights[light as usize] {
            l @ Light::Area { .. } => {
                let local = warp::cosine_hemisphere(u);
                let d = (local.z > 0.0).then(|| Frame::from_normal(v.n).to_world(local))?;
                if !tech.guides_emission(l) {
                    return Some(d);
                }
                // eq. (5.17) where guiding is on
                tech.sample_emission(scene, l, (v.p, v.n), d, u, sampler)
                    .map(|(d, _)| d)
            }
            Light::Point { .. } => Some(warp::uniform_sphere(u)),
            Light::Spot {
                frame, cos_total, ..
            } => Some(frame.to_world(warp::uniform_cone(u, *cos_total))),
            _ => None,
        },
        VertexKind::Surface { .. } | VertexKind::Medium { .. } => {
            // the BSDF or phase function, or the guided mixture (the technique's)
            let wo = (prev?.p - v.p).normalize_or_zero();
            tech.sample_scatter_with(scene, v, wo, mode, u, sampler)
                .filter(|s| s.pdf > 0.0)
                .map(|s| s.wi)
        }
        _ => None,
    }
}

/// The next vertex along `d` from `v`, with a free-flight distance sampled by Table 1
/// (`Scene::propagate`); `None` when the ray escapes.
pub fn extend(scene: &Scene, v: &Vertex, d: Vec3, sampler: &mut Sampler) -> Option<Vertex> {
    let (ray, lead, medium) = ray_from(scene, v, d);
    let prop = scene.propagate_from(ray, lead, medium, v.is_camera(), sampler);
    if prop.pdf <= 0.0 {
        return None;
    }
    match prop.event {
        Event::Escape => None,
        Event::Medium { p, medium: m, .. } => Some(Vertex::new(
            VertexKind::Medium { medium: m },
            p,
            Vec3::ZERO,
            Some(m),
            Some(m),
        )),
        Event::Surface { hit, medium } => Some(Vertex::on_surface(scene, &hit, medium)),
    }
}

/// A light vertex sampled as a light subpath starts (`path::technique::sample_emitted_start`):
/// a light by power, a point on it by the technique (the adjoint image's start density,
/// Kristensen 2010, sec. 5.3.1, which the bidirectional mutation's transition density evaluates
/// through `light_origin_pdf`) or by area, in the medium around the light
/// (`Scene::light_media`).
pub fn sample_light_vertex(
    scene: &Scene,
    tech: &dyn LocalSampling,
    sampler: &mut Sampler,
) -> Option<Vertex> {
    if scene.lights.is_empty() {
        return None;
    }
    let start = crate::path::technique::sample_emitted_start(tech, scene, sampler)?;
    let (l, es, prim) = (start.light, start.es, start.prim);
    if scene.lights[l].is_infinite() {
        // the direction w alone (the disk point is drawn again by `extend_from_infinite`)
        let w = -es.d;
        return (es.pdf_dir > 0.0 && w.is_finite()).then(|| infinite_vertex(l as u32, w, es.p));
    }
    if prim.is_none() && !matches!(scene.lights[l], Light::Point { .. } | Light::Spot { .. }) {
        return None;
    }
    if es.pdf_pos <= 0.0 {
        return None;
    }
    let lm = scene.light_medium(l, prim);
    let n = if prim.is_some() { es.n } else { Vec3::ZERO };
    Some(Vertex::new(
        VertexKind::Light {
            light: l as u32,
            prim,
        },
        es.p,
        n,
        lm,
        lm,
    ))
}

/// The vertex of light `light` at infinity in direction `w` (towards the light), placed at
/// `p` until `contribution::anchor_infinite` puts it on its path's first edge.
pub fn infinite_vertex(light: u32, w: Vec3, p: Vec3) -> Vertex {
    Vertex::new(
        VertexKind::InfiniteLight { light, w },
        p,
        Vec3::ZERO,
        None,
        None,
    )
}

/// The vertex x_1 that a light subpath reaches from a light at infinity `v`: a point uniform on
/// the disk of the scene's radius facing the light (`Light::sample_le`), its ray along -w, a
/// free-flight distance by Table 1. Its density is g(x_1) / (pi R^2) times the propagation pdf
/// (`Vertex::light_pdf_to`): the disk's uniform density per area perpendicular to w.
pub fn extend_from_infinite(scene: &Scene, v: &Vertex, sampler: &mut Sampler) -> Option<Vertex> {
    let VertexKind::InfiniteLight { w, .. } = v.kind else {
        return None;
    };
    let u = sampler.next_2d();
    let frame = Frame::from_normal(w);
    let disk = warp::concentric_disk(u) * scene.radius;
    let origin = scene.center + w * scene.radius + frame.s * disk.x + frame.t * disk.y;
    let mut start = *v;
    start.p = origin;
    extend(scene, &start, -w, sampler)
}

/// [`extend`], with the environment light's vertex where the ray escapes (`None` there without
/// an environment): an eye subpath that reaches the light by itself. The same random numbers as
/// `extend`.
pub fn extend_or_escape(
    scene: &Scene,
    v: &Vertex,
    d: Vec3,
    sampler: &mut Sampler,
) -> Option<Vertex> {
    let (ray, lead, medium) = ray_from(scene, v, d);
    let prop = scene.propagate_from(ray, lead, medium, v.is_camera(), sampler);
    if prop.pdf <= 0.0 {
        return None;
    }
    match prop.event {
        Event::Escape => {
            let env = scene.environment?;
            Some(infinite_vertex(
                env,
                d,
                v.p + d * infinite_distance(scene, v.p),
            ))
        }
        Event::Medium { p, medium: m, .. } => Some(Vertex::new(
            VertexKind::Medium { medium: m },
            p,
            Vec3::ZERO,
            Some(m),
            Some(m),
        )),
        Event::Surface { hit, medium } => Some(Vertex::on_surface(scene, &hit, medium)),
    }
}

/// The environment's vertex in direction `d` from `v` when the ray meets no non-null surface
/// (it passes through media: their transmittance enters f, not the proposal).
pub fn escape_to_environment(scene: &Scene, v: &Vertex, d: Vec3) -> Option<Vertex> {
    let env = scene.environment?;
    let (ray, _, medium) = ray_from(scene, v, d);
    for seg in segments_from(scene, v, ray, medium) {
        match seg.end {
            SegmentEnd::Null(_) => {}
            SegmentEnd::Open => {
                return Some(infinite_vertex(
                    env,
                    d,
                    v.p + d * infinite_distance(scene, v.p),
                ))
            }
            SegmentEnd::Surface(_) => return None,
        }
    }
    None
}

/// The light vertex x0 of a new light subpath, as BDPT's light subpaths start
/// (`Bdpt::light_subpath`): a volume vertex of the glowing media with their share of the
/// emitted power (`scene::emitters::volume_share`, a number drawn only when some medium
/// glows), else a light by [`sample_light_vertex`]. Its density is
/// `Vertex::light_origin_pdf`, the share included on both sides.
pub fn sample_start_vertex(
    scene: &Scene,
    tech: &dyn LocalSampling,
    sampler: &mut Sampler,
) -> Option<Vertex> {
    let volume = crate::scene::emitters::volume_share(scene);
    if volume > 0.0 && (volume >= 1.0 || sampler.next_f32() < volume) {
        return sample_volume_start(scene, sampler);
    }
    sample_light_vertex(scene, tech, sampler)
}

/// A volume vertex x0 drawn from the emitting media by emitted power (eq. 5's L_e(x0 -> x1)
/// with x0 in the medium; density per unit volume `scene.emitters.pdf`); `None` when the
/// point falls outside its medium (the lattice's cells reach past it) or does not glow.
pub fn sample_volume_start(scene: &Scene, sampler: &mut Sampler) -> Option<Vertex> {
    let u_select = sampler.next_f32();
    let u = Vec3::new(sampler.next_f32(), sampler.next_f32(), sampler.next_f32());
    let vs = scene.emitters.sample(scene, u_select, u)?;
    if scene.medium_at(vs.p) != Some(vs.medium) || vs.emission == crate::spectrum::Rgb::ZERO {
        return None;
    }
    let m = Some(vs.medium);
    Some(Vertex::new(
        VertexKind::Medium { medium: vs.medium },
        vs.p,
        Vec3::ZERO,
        m,
        m,
    ))
}

/// True for a volume vertex in a medium that glows: where a path may start (x0 of eq. 5).
pub fn is_volume_start(scene: &Scene, v: &Vertex) -> bool {
    match v.kind {
        VertexKind::Medium { medium } => scene.media[medium as usize].emits(),
        _ => false,
    }
}

/// The direction a volume start x0 emits along: uniform on the sphere (L_e,V0 is
/// isotropic; density 1 / (4 pi), `Vertex::light_pdf_to`).
pub fn sample_volume_direction(sampler: &mut Sampler) -> Vec3 {
    warp::uniform_sphere(sampler.next_2d())
}

/// The first non-null surface along `d` from `v`, no collisions sampled (the ray passes
/// through media; their transmittance enters f, not the proposal).
pub fn trace_surface(scene: &Scene, v: &Vertex, d: Vec3) -> Option<Vertex> {
    let (ray, _, medium) = ray_from(scene, v, d);
    for seg in segments_from(scene, v, ray, medium) {
        match seg.end {
            SegmentEnd::Null(_) => {}
            SegmentEnd::Open => return None,
            SegmentEnd::Surface(hit) => return Some(Vertex::on_surface(scene, &hit, seg.medium)),
        }
    }
    None
}

/// A medium vertex at distance `dist` along `d` from `v`; `None` when a surface comes first or
/// no medium is there.
pub fn point_along(scene: &Scene, v: &Vertex, d: Vec3, dist: f32) -> Option<Vertex> {
    if !(dist > 0.0 && dist.is_finite()) {
        return None;
    }
    let (ray, lead, medium) = ray_from(scene, v, d);
    for seg in segments_from(scene, v, ray, medium) {
        match seg.end {
            SegmentEnd::Null(h) if h.t + lead < dist => {}
            SegmentEnd::Surface(h) if h.t + lead < dist => return None,
            _ => {
                let m = seg.medium?;
                return Some(Vertex::new(
                    VertexKind::Medium { medium: m },
                    v.p + d * dist,
                    Vec3::ZERO,
                    Some(m),
                    Some(m),
                ));
            }
        }
    }
    None
}

/// How a retraced chain ends (the old end vertex's kind: the characteristic is kept).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChainEnd {
    /// A surface with a regular (non-singular) BSDF.
    Surface,
    /// A medium vertex at this distance from its predecessor.
    Medium { dist: f32 },
    /// A point on an area light.
    Light,
    /// The environment light at infinity: the ray escapes (a directional light's one direction
    /// is never met by a turned ray: the callers leave such chains alone).
    Environment,
}

/// The end of the old chain whose vertex is `end` and whose predecessor in tracing order is at
/// `before`.
pub fn chain_end_of(scene: &Scene, end: &Vertex, before: Vec3) -> ChainEnd {
    if end.is_medium() {
        ChainEnd::Medium {
            dist: (end.p - before).length(),
        }
    } else if matches!(end.kind, VertexKind::Light { .. }) {
        ChainEnd::Light
    } else if end.is_infinite_light() {
        ChainEnd::Environment
    } else {
        let _ = scene;
        ChainEnd::Surface
    }
}

/// Retraces a chain from `start` along `d`: one specular vertex per entry of `lobes`, each
/// continued in that lobe, then the end vertex. The new vertices are appended to `out` in
/// tracing order (a caller's buffer: the perturbations retrace once per mutation).
// ANCHOR: retrace_chain
pub fn retrace_chain(
    scene: &Scene,
    start: &Vertex,
    d: Vec3,
    lobes: impl IntoIterator<Item = Lobe>,
    end: ChainEnd,
    out: &mut Vec<Vertex>,
) -> Option<()> {
    let mut cur = *start;
    let mut d = d;
    for lobe in lobes {
        let v = trace_surface(scene, &cur, d)?;
        let bsdf = singular_bsdf(scene, &v)?;
        let s = specular_sample(bsdf, -d, v.normals(), lobe, TransportMode::Radiance)?;
        out.push(v);
        d = s.wi;
        cur = v;
    }
    let v = match end {
        ChainEnd::Medium { dist } => point_along(scene, &cur, d, dist)?,
        ChainEnd::Surface => {
            let v = trace_surface(scene, &cur, d)?;
            let b = v.bsdf(scene)?;
            if !b.has_regular_lobe() {
                return None;
            }
            v
        }
        ChainEnd::Light => {
            let v = trace_surface(scene, &cur, d)?;
            let VertexKind::Surface { prim } = v.kind else {
                return None;
            };
            let light = scene.shapes[scene.prim_shape[prim as usize] as usize].light?;
            let mut l = v;
            l.kind = VertexKind::Light {
                light,
                prim: Some(prim),
            };
            l
        }
        ChainEnd::Environment => escape_to_environment(scene, &cur, d)?,
    };
    out.push(v);
    Some(())
}
// ANCHOR_END: retrace_chain

/// `w` turned by polar angle `theta` and azimuth `phi` about itself.
pub fn perturb_direction(w: Vec3, theta: f32, phi: f32) -> Vec3 {
    let (s, c) = theta.sin_cos();
    Frame::from_normal(w)
        .to_world(Vec3::new(s * phi.cos(), s * phi.sin(), c))
        .normalize()
}

/// The angle between unit vectors, accurate for small angles.
pub fn angle_between(a: Vec3, b: Vec3) -> f32 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Unit direction from `a` to `b`.
#[inline]
pub fn dir(a: &Vertex, b: &Vertex) -> Vec3 {
    (b.p - a.p).normalize_or_zero()
}
