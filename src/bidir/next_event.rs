//! Strategy s = 1, next-event estimation: a light vertex sampled for the eye subpath's end (by
//! the technique's light start or by power), in the medium around its light
//! (`Scene::light_media`), and its connection.

use glam::{Vec2, Vec3};

use super::connect::Connection;
use super::{volume_share, Bdpt, Strategies};
use crate::math::Sampler;
use crate::path::geometry_term::cosine_factor;
use crate::path::subpath::Subpath;
use crate::path::technique::StartDraw;
use crate::path::{Vertex, VertexKind};
use crate::scene::light::{LightPointDraw, LightSample};
use crate::scene::{Light, Scene};
use crate::spectrum::Rgb;

impl Bdpt<'_> {
    /// Strategy s = 1 (next-event estimation): a light vertex sampled for the eye subpath's
    /// end `eye[t - 1]`, by the technique's light start or by power, and its connection.
    pub(super) fn connect_light_sample<E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        eye_path: &E,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<Connection> {
        let pt = &eye_path.vertices()[t - 1];
        if !pt.is_connectible(scene) {
            return None;
        }
        // the lights or the emitting media, by power (a number drawn only when some medium
        // glows)
        let volume = volume_share(scene);
        if volume > 0.0 && (volume >= 1.0 || sampler.next_f32() < volume) {
            return self.connect_volume_sample(scene, eye_path, t, sampler);
        }
        let (li, ls, sel_pdf, start_prim) = self.sample_light_for(scene, pt.p, sampler)?;
        let mut v = self.light_sample_vertex(scene, li, &ls, start_prim, pt.p);
        v.beta = ls.value / (sel_pdf * (1.0 - volume));
        let (f, raster) = Self::eye_end_factor(scene, eye_path, t, &v, ls.wi)?;
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

    /// Strategy s = 1 with a volume vertex x0 of the emitting media as the light vertex: a
    /// point by emitted power, density per unit volume (selection included), connected to the
    /// eye subpath's end pt with G = g(pt) / r^2 (x0 emits isotropically, no cosine there).
    fn connect_volume_sample<E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        eye_path: &E,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<Connection> {
        let pt = &eye_path.vertices()[t - 1];
        let u_select = sampler.next_f32();
        let u = Vec3::new(sampler.next_f32(), sampler.next_f32(), sampler.next_f32());
        let vs = scene.emitters.sample(scene, u_select, u)?;
        if scene.medium_at(vs.p) != Some(vs.medium) || vs.emission == Rgb::ZERO {
            return None;
        }
        let m = Some(vs.medium);
        let mut v = Vertex::new(
            VertexKind::Medium { medium: vs.medium },
            vs.p,
            Vec3::ZERO,
            m,
            m,
        );
        v.pdf_fwd = v.light_origin_pdf(scene, self.tech);
        let d2 = (v.p - pt.p).length_squared();
        if v.pdf_fwd.is_nan() || v.pdf_fwd <= 0.0 || d2 == 0.0 {
            return None;
        }
        let wi = (v.p - pt.p) / d2.sqrt();
        // L_e,V0 G / p with G's 1 / r^2 here and g(pt) below
        v.beta = vs.emission / (v.pdf_fwd * d2);
        let (f, raster) = Self::eye_end_factor(scene, eye_path, t, &v, wi)?;
        if f == Rgb::ZERO {
            return None;
        }
        let e = scene.edge(v.edge_end(pt.p), pt.edge_end(v.p), sampler);
        if e.transmittance == Rgb::ZERO {
            return None;
        }
        let l = pt.beta * f * v.beta * e.transmittance * cosine_factor(pt, wi);
        let (pdf_qp, pdf_pq) = (e.pdf_ab, e.pdf_ba);
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

    /// A light sample for the point `p`: the light `li` and its sample, with `sel_pdf` the
    /// solid-angle density with the light selection included, and the area light's primitive;
    /// from the technique's light start (as light subpaths start) or by power.
    fn sample_light_for(
        &self,
        scene: &Scene,
        p: Vec3,
        sampler: &mut Sampler,
    ) -> Option<(usize, LightSample, f32, Option<u32>)> {
        let (mut li, pmf, u_prim) = scene.light_distr.sample(sampler.next_f32());
        let u = sampler.next_2d();
        let (ls, sel_pdf, start_prim) = match self.tech.sample_light_start(scene, li, u, sampler) {
            StartDraw::Failed => return None,
            StartDraw::Drawn(st) => {
                // the light vertex from the technique, as light subpaths start
                li = st.point.light as usize;
                let (light, prim) = (&scene.lights[li], st.point.prim);
                let ls = light.li_from(&scene.prims, prim, p, st.point.p, st.point.n, st.pdf)?;
                (ls, ls.pdf, Some(st.point.prim))
            }
            StartDraw::ByPower => {
                // by area, as light subpaths start: the weights take that density
                let light = &scene.lights[li];
                let ls = light.sample_li(&scene.prims, p, (u, u_prim), LightPointDraw::Area)?;
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
        Some((li, ls, sel_pdf, start_prim))
    }

    /// What the eye subpath's end pt = `eye[t - 1]` gives the light vertex `v` in direction
    /// `wi` (from pt): for the sensor itself (t = 1), W_e over the density of its point (1 for
    /// the pinhole, whose W_e lands in another pixel, the raster position returned; the lens
    /// point's 1 / (pi r^2) for a thin lens; A * (1/A) for a meter); otherwise
    /// `f_hat(v -> pt -> eye[t - 2])`.
    fn eye_end_factor<E: Subpath + ?Sized>(
        scene: &Scene,
        eye_path: &E,
        t: usize,
        v: &Vertex,
        wi: Vec3,
    ) -> Option<(Rgb, Option<Vec2>)> {
        let pt = &eye_path.vertices()[t - 1];
        if t > 1 {
            let f = pt.f_hat_dirs(
                scene,
                (v.p - pt.p).normalize_or_zero(),
                eye_path.to_prev(t - 1),
            );
            return Some((f, None));
        }
        match pt.kind {
            VertexKind::Camera => {
                let imp = scene.camera.as_ref()?.importance(pt.p, wi)?;
                Some((Rgb::splat(imp.we) / pt.pdf_fwd, Some(imp.raster)))
            }
            VertexKind::Meter { .. } => Some((pt.importance(scene, pt.p + wi) / pt.pdf_fwd, None)),
            _ => None,
        }
    }

    /// The light vertex of next-event estimation's sample `ls` of light `li` (seen from
    /// `p_ref`; on primitive `start_prim` of an area light), with its origin density; an
    /// infinite light's vertex is placed beyond the scene along the sampled direction.
    fn light_sample_vertex(
        &self,
        scene: &Scene,
        li: usize,
        ls: &LightSample,
        start_prim: Option<u32>,
        p_ref: Vec3,
    ) -> Vertex {
        let light_ref = &scene.lights[li];
        let lm = scene.light_medium(li, start_prim);
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
}
