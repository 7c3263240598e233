//! The weights of BDPT's strategies (Veach 1997, sec. 10.2), by the balance or the power
//! heuristic ([`MisHeuristic`]): the ratio of
//! neighbouring splits' densities at every vertex, with the four reverse densities next to the
//! connection recomputed for the joined path (`Changed`), all in the vertices' own measures
//! with the propagation pdfs of Table 1.

use glam::Vec3;

use super::Bdpt;
use crate::bsdf::TransportMode;
use crate::path::geometry_term::cosine_factor;
use crate::path::geometry_term::to_area;
use crate::path::subpath::{fwd_density, remap, rev_density, Subpath};
use crate::path::{Vertex, VertexKind};
use crate::scene::Scene;

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

/// The reverse densities (in their vertices' measures, propagation included) that a
/// connection (s, t) gives the vertices next to it: p_{t-1}, p_{t-2} as sampled from the light
/// side and q_{s-1}, q_{s-2} as sampled from the eye side (Veach 1997, sec. 10.2); those of
/// vertices the path does not have are unused.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Changed {
    pub(super) pt: f32,
    pub(super) pt_minus: f32,
    pub(super) qs: f32,
    pub(super) qs_minus: f32,
}

/// The eye side's end p of a connection from a light walk's vertex q: the solid-angle
/// density with which p samples the direction to q, and, when p has a predecessor, the one
/// with which it samples the predecessor given q, with the conversion to its measure.
pub(super) struct End<'a> {
    pub(super) p: &'a Vertex,
    pub(super) p_to_q: f32,
    pub(super) p_minus: Option<(f32, crate::path::geometry_term::AreaFactor)>,
}

/// How BDPT's strategies share a path (Veach 1997, sec. 9.2): strategy s gets
/// p_s^beta / sum_i p_i^beta of it, with beta = 1 (balance) or 2 (power). Written with the
/// ratios r_i = p_i / p_s that the weights are built from, 1 / sum_i r_i^beta.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum MisHeuristic {
    /// beta = 1 (the default): in the media this project renders, many strategies of a path
    /// have densities of one order, and squaring the ratios gives the best of them more of
    /// the path than its variance warrants (book: "Bidirectional path tracing", "Which
    /// heuristic").
    #[default]
    Balance,
    /// beta = 2, Veach's recommendation for scenes where one strategy is far better than the
    /// others.
    Power,
}

crate::option_value!(MisHeuristic, "MIS heuristic");

impl MisHeuristic {
    /// r^beta: a ratio of densities as the heuristic counts it.
    #[inline]
    pub fn term(self, r: f32) -> f32 {
        match self {
            MisHeuristic::Balance => r,
            MisHeuristic::Power => r * r,
        }
    }
}

impl Bdpt<'_> {
    /// Whether light `l` is a Dirac in position or direction (it cannot be hit by chance).
    fn is_delta_light(scene: &Scene, v: &Vertex) -> bool {
        match v.kind {
            VertexKind::Light { light, .. } | VertexKind::InfiniteLight { light, .. } => {
                scene.lights[light as usize].is_delta()
            }
            _ => false,
        }
    }

    /// The weight of strategy (s, t) for the path joined from `light[..s]` and
    /// `eye[..t]`, with `sampled` replacing the endpoint that was sampled for the connection
    /// (s = 1 or t = 1). `conn` holds the connection edge's propagation pdfs.
    // ANCHOR: mis_weight
    pub fn mis_weight(&self, scene: &Scene, light: &[Vertex], eye: &[Vertex], join: Join) -> f32 {
        let changed = self.changed_densities(scene, light, eye, &join);
        self.weight(scene, light, eye, &join, changed)
    }

    /// The four reverse densities the connection `join` changes, from the vertices alone.
    pub(super) fn changed_densities(
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

    /// The weight 1 / (1 + sum of r_i^beta) of strategy `join` with the reverse densities
    /// `changed` of the four vertices next to the connection; every other vertex brings its
    /// subpath's own ratio (`Subpath::ratio`).
    pub(super) fn weight<L: Subpath + ?Sized, E: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light: &L,
        eye: &E,
        join: &Join,
        changed: Changed,
    ) -> f32 {
        let h = self.heuristic;
        let sum = Self::eye_sum(eye, join, &changed, h);
        if join.s == 0 {
            return 1.0 / (1.0 + sum);
        }
        1.0 / (1.0 + Self::light_sum(scene, light, join, &changed, (sum, h)))
    }

    /// The sum of r_i^beta over the eye subpath's side of strategy `join` (vertices that would
    /// need to hit a Dirac left out; the connection's ends are connectible, so their deltas
    /// count as false).
    fn eye_sum<E: Subpath + ?Sized>(
        eye: &E,
        join: &Join,
        changed: &Changed,
        h: MisHeuristic,
    ) -> f32 {
        let t = join.t;
        let ev = eye.vertices();
        let mut sum = 0.0f32;
        let mut ri = 1.0f32;
        // vertices i >= 1 only: the ends' densities are those of a predecessor ev[i - 1]
        for i in (1..t).rev() {
            ri *= if i + 1 == t {
                // the connection's end is no Dirac vertex in the joined path
                remap(changed.pt) / remap(fwd_density(&ev[i - 1], &ev[i], false))
            } else if i + 2 == t {
                let v = &ev[i];
                let rev = rev_density(v, &ev[t - 1], changed.pt_minus, v.delta);
                remap(rev) / remap(fwd_density(&ev[i - 1], v, v.delta))
            } else {
                eye.ratio(i)
            };
            let delta = i + 1 != t && ev[i].delta;
            if !delta && !ev[i - 1].delta {
                sum += h.term(ri);
            }
        }
        sum
    }

    /// `sum` plus the r_i^beta over the light subpath's side of strategy `join` (s >= 1), in
    /// that order of additions.
    fn light_sum<L: Subpath + ?Sized>(
        scene: &Scene,
        light: &L,
        join: &Join,
        changed: &Changed,
        (mut sum, h): (f32, MisHeuristic),
    ) -> f32 {
        let s = join.s;
        let lv = light.vertices();
        let qs = if s == 1 {
            join.sampled.as_ref().unwrap_or_else(|| &lv[0])
        } else {
            &lv[s - 1]
        };
        // the density of light vertex i sampled from its predecessor (none for i = 0)
        let fwd = |i: usize, v: &Vertex, dirac: bool| match i.checked_sub(1) {
            Some(a) => fwd_density(&lv[a], v, dirac),
            None => v.pdf_fwd,
        };
        let mut ri = 1.0f32;
        for i in (0..s).rev() {
            ri *= if i + 1 == s {
                remap(changed.qs) / remap(fwd(i, qs, false))
            } else if i + 2 == s {
                let v = &lv[i];
                let rev = rev_density(v, qs, changed.qs_minus, v.delta);
                remap(rev) / remap(fwd(i, v, v.delta))
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
                sum += h.term(ri);
            }
        }
        sum
    }

    /// [`Bdpt::changed_densities`] of a connection from the light walk's vertex q =
    /// `light[s - 1]` (s >= 2) to the end `ends.p` of the eye side, from the connection's
    /// vector `d` = p - q and its unit direction `w`, with q's per-vertex values and p's
    /// densities given: the same operands the vertices would give, so the same bits.
    pub(super) fn changed_at_walk<L: Subpath + ?Sized>(
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

    /// [`Bdpt::changed_densities`] of next-event estimation's connection (s = 1, t >= 2) of
    /// light vertex `q` to p = `eye[t - 1]`, with p's per-vertex values: the operands the
    /// vertices would give, so the same bits.
    pub(super) fn changed_at_light<E: Subpath + ?Sized>(
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
}

/// The weight (by `bdpt`'s heuristic) of strategy (s, t = k + 1 - s) for an explicit path
/// x_0 ... x_k, with every density recomputed from the geometry ([`crate::path::pdf::densities`]): the
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
            x.prop_fwd = if i > 0 { d.prop_up[i - 1] } else { 1.0 };
            x
        })
        .collect();
    let mut eye: Vec<Vertex> = Vec::with_capacity(t);
    for i in (s..n).rev() {
        let mut x = v[i];
        x.pdf_fwd = d.eye[i];
        x.pdf_rev = d.light[i];
        x.prop_rev = if i + 1 < n { d.prop_up[i] } else { 1.0 };
        x.prop_fwd = if i + 1 < n { d.prop_down[i] } else { 1.0 };
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
