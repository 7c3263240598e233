//! Strategy t = 1, light tracing's connection: the light subpath's end joined to the camera or
//! to a point sampled on a meter, and the meter connection of the `light` integrator, whose two
//! direction samplers are combined by MIS.

use glam::{Vec2, Vec3};

use super::connect::Connection;
use super::mis::End;
use super::{Bdpt, Strategies};
use crate::bsdf::TransportMode::Radiance;
use crate::geometry::Primitive;
use crate::math::Sampler;
use crate::path::geometry_term::cosine_factor;
use crate::path::subpath::Subpath;
use crate::path::{Vertex, VertexKind};
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// The sensor vertex of a t = 1 connection, W_e towards the light subpath's end, the sensor's
/// density of that direction when it comes with W_e (the camera's) and the raster position.
struct SensorEnd {
    sensor: Vertex,
    we: Rgb,
    pdf_dir: Option<f32>,
    raster: Option<Vec2>,
}

impl Bdpt<'_> {
    /// Strategy t = 1 (light tracing's connection): the light subpath's end `light[s - 1]`
    /// joined to the camera or to a point sampled on the meter of `eye[0]`.
    pub(super) fn connect_to_sensor<L: Subpath + ?Sized>(
        &self,
        scene: &Scene,
        light_path: &L,
        eye: &[Vertex],
        s: usize,
        sampler: &mut Sampler,
    ) -> Option<Connection> {
        let qs = &light_path.vertices()[s - 1];
        if !qs.is_connectible(scene) || s < 2 {
            return None;
        }
        let SensorEnd {
            sensor,
            we,
            pdf_dir: sensor_pdf,
            raster,
        } = Self::sensor_towards(scene, &eye[0], qs.p, sampler)?;
        // 1 / p(z_0): the pinhole's Dirac gives 1
        let area_inv = 1.0 / sensor.pdf_fwd;
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

    /// The sensor's end of a connection to the point `q`: the pinhole camera vertex `z0`
    /// itself, a point sampled uniformly on a thin lens (its density 1 / (pi r^2) in
    /// `pdf_fwd`), or a point sampled uniformly on the meter of `z0` (W_e / p(x) = (1/A) /
    /// (1/A) in its throughput), with W_e towards `q` and, for the camera, the density of
    /// sampling `q`'s direction and the raster position, from the one importance evaluation
    /// both need.
    fn sensor_towards(
        scene: &Scene,
        z0: &Vertex,
        q: Vec3,
        sampler: &mut Sampler,
    ) -> Option<SensorEnd> {
        Some(match z0.kind {
            VertexKind::Camera => {
                let cam = scene.camera.as_ref()?;
                let lens = cam.sample_lens(sampler);
                let imp = cam.importance(lens, (q - lens).normalize_or_zero())?;
                let mut v = *z0;
                v.p = lens;
                v.pdf_fwd = cam.lens_pdf_area();
                v.beta = Rgb::ONE;
                SensorEnd {
                    sensor: v,
                    we: Rgb::splat(imp.we),
                    pdf_dir: Some(imp.pdf_dir),
                    raster: Some(imp.raster),
                }
            }
            VertexKind::Meter { meter } => {
                let quad = Primitive::Quad(scene.sensors[meter as usize].quad);
                let (p, n) = quad.sample_area(sampler.next_2d());
                let mut v = Vertex::new(z0.kind, p, n, z0.medium_front, z0.medium_back);
                v.pdf_fwd = 1.0 / quad.area();
                v.beta = Rgb::ONE;
                SensorEnd {
                    sensor: v,
                    we: v.importance(scene, q),
                    pdf_dir: None,
                    raster: None,
                }
            }
            _ => return None,
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
    pub(super) fn light_tracing_meter(
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
