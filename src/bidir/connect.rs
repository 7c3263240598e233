//! One strategy (s, t) of a pair of subpaths: the eye subpath's own hit of a light (s = 0),
//! next-event estimation (s = 1, [`super::next_event`]), the connection to the sensor (t = 1,
//! [`super::sensor`]) or the edge between the two subpaths' ends, MIS-weighted unless the
//! strategies are used alone.

use glam::Vec2;

use super::mis::{Changed, End, Join};
use super::{Bdpt, Strategies};
use crate::bsdf::TransportMode;
use crate::math::Sampler;
use crate::path::geometry_term::cosine_factor;
use crate::path::subpath::Subpath;
use crate::path::{Vertex, VertexKind};
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// One strategy's unweighted contribution, the propagation pdfs of its connection edge (both
/// directions), the endpoint it sampled and the raster position it lands on.
pub(super) struct Connection {
    pub(super) l: Rgb,
    pub(super) pdf_qp: f32,
    pub(super) pdf_pq: f32,
    pub(super) sampled: Option<Vertex>,
    pub(super) raster: Option<Vec2>,
    /// The reverse densities the connection changes, when it computed them on the way.
    pub(super) changed: Option<Changed>,
}

impl Bdpt<'_> {
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
                if depth < scene.min_depth() as i64 || depth as u64 > self.max_depth as u64 {
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
        let c = self.unweighted(scene, light_path, eye_path, s, t, sampler)?;
        let (mut l, raster, sampled) = (c.l, c.raster, c.sampled);
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
                pdf_qp: c.pdf_qp,
                pdf_pq: c.pdf_pq,
            };
            let changed =
                (c.changed).unwrap_or_else(|| self.changed_densities(scene, light, eye, &join));
            l *= self.weight(scene, light_path, eye_path, &join, changed);
        }
        Some((l, raster, sampled))
    }

    /// Strategy (s, t) unweighted, by the connection that samples it: the eye subpath's own
    /// hit of an emitter (s = 0), next-event estimation (s = 1), light tracing's connection to
    /// a meter with its two direction samplers, the connection to the sensor (t = 1), or the
    /// edge between the two subpaths' ends.
    fn unweighted<L: Subpath + ?Sized, E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light_path: &L,
        eye_path: &E,
        s: usize,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<Connection> {
        let (light, eye) = (light_path.vertices(), eye_path.vertices());
        let plain = |l: Rgb, sampled: Option<Vertex>| Connection {
            l,
            pdf_qp: 1.0,
            pdf_pq: 1.0,
            sampled,
            raster: None,
            changed: None,
        };
        if s == 0 {
            // the eye subpath found an emitter by itself
            let pt = &eye[t - 1];
            let towards = eye[t - 2].p;
            let l = match pt.kind {
                VertexKind::InfiniteLight { .. } => pt.emitted(scene, towards),
                _ => pt.surface_emission(scene, towards),
            } * pt.beta;
            Some(plain(l, None))
        } else if s == 1 {
            // next-event estimation: sample a point on a light for the eye subpath's end
            self.connect_light_sample(scene, eye_path, t, sampler)
        } else if t == 1
            && self.strategies == Strategies::LightTracing
            && matches!(eye[0].kind, VertexKind::Meter { .. })
        {
            // light tracing to a meter: two direction samplers combined by MIS
            if !light[s - 1].is_connectible(scene) || s < 2 {
                return None;
            }
            let (l, z0) = self.light_tracing_meter(scene, light, s, &eye[0], sampler)?;
            Some(plain(l, Some(z0)))
        } else if t == 1 {
            // connect the light subpath to the sensor
            self.connect_to_sensor(scene, light_path, eye, s, sampler)
        } else {
            self.connect_walks(scene, light_path, eye_path, s, t, sampler)
        }
    }

    /// Strategy (s, t) with s, t >= 2: the light subpath's end q joined to the eye subpath's
    /// end p. Returns the unweighted contribution, the edge's propagation pdfs both ways and,
    /// when every strategy is weighted, the reverse densities the connection changes, all from
    /// one direction q -> p (its reverse is the same vector negated, exactly).
    fn connect_walks<L: Subpath + ?Sized, E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light: &L,
        eye: &E,
        s: usize,
        t: usize,
        sampler: &mut Sampler,
    ) -> Option<Connection> {
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
        Some(Connection {
            l,
            pdf_qp: e.pdf_ab,
            pdf_pq: e.pdf_ba,
            sampled: None,
            raster: None,
            changed,
        })
    }
    // ANCHOR_END: connect
}
